"""Signals at random points of real curve and surface runs (exports included): every OUT is either complete
and consistent or untouched; Ctrl-C and SIGTERM are answered with a "stopping..." line and a prompt exit."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from cli_subprocess import TINY_CURVE, assert_clean, gsr, popen

from gsr_cad.reconstruct.meshio import load_mesh
from gsr_cad.reconstruct.result import Result
from gsr_cad.reconstruct.samples import get_sample

STOP_SECONDS = 10.0
"""Longest time from the first signal to the exit (5 s asked; the margin is for a loaded test machine)."""
CORE = {"result.json", "control_points.csv", "control_mesh.obj", "limit_mesh.obj", "report.png", "report.html",
        "run.json"}
RUNS = {
    "curve": ("bspline_12", "c.csv", ("--generations", "40", "--stall-generations", "0", "--population", "100",
                                      "--initial-population", "400")),
    "surface": ("inset_extrude", "t.obj", ("--generations", "3")),
}
EXPORTS = {"curve": {"curve_blender.py", "curve_cadquery.py", "curve.dxf", "curve.FCMacro", "curve.scad",
                     "curve.step", "curve.svg", "exports.json"}}


def _argv(kind: str, d: Path, out: Path) -> list:
    name, file, flags = RUNS[kind]
    path = d / file
    if not path.exists():
        get_sample(name).write(path)
    return [kind, path, "-o", out, "--seed", "1", *flags]


def _kill_children_of_run(marker: str) -> None:
    """SIGKILL, by pid, the processes this test started whose command line names ``marker`` (its OUT)."""
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if marker in cmdline and int(entry.name) != os.getpid():
                with contextlib.suppress(OSError):
                    os.kill(int(entry.name), signal.SIGKILL)


class Watched:
    """A running gsr process whose stderr is collected line by line."""

    def __init__(self, argv: list, cwd: Path) -> None:
        self.proc = popen(argv, cwd)
        self.marker = str(argv[argv.index("-o") + 1])  # this run's own OUT path: names its processes
        self.err: list[str] = []
        self.out = ""
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stderr:
            self.err.append(line)

    def wait_for(self, marker: str, timeout: float = 120.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end and self.proc.poll() is None:
            if any(marker in line for line in self.err):
                return True
            time.sleep(0.02)
        return False

    def finish(self, timeout: float = 120.0) -> float:
        """Wait for the exit; returns the seconds it took."""
        started = time.monotonic()
        self.proc.wait(timeout=timeout)
        took = time.monotonic() - started
        chunks: list[str] = []
        drain = threading.Thread(target=lambda: chunks.append(self.proc.stdout.read()), daemon=True)
        drain.start()
        drain.join(10)
        self._reader.join(10)
        left = drain.is_alive() or self._reader.is_alive()  # a child still holds the pipes: it outlived gsr
        if left:
            _kill_children_of_run(self.marker)
        assert not left, "a child process of gsr is still running after it exited"
        self.out = "".join(chunks)
        return took


def _check_out(out: Path, kind: str, killed: bool) -> str:
    """'untouched' or 'complete'; fails on anything half done."""
    if not out.exists() or not any(out.iterdir()):
        return "untouched"
    names = {p.name for p in out.iterdir()}
    hidden = {n for n in names if n.startswith(".")}
    assert killed or not hidden, f"leftovers {hidden} in {out}"
    result = Result.load(out / "result.json")
    if "control_points.csv" in names:
        pts = np.loadtxt(out / "control_points.csv", delimiter=",", skiprows=1, ndmin=2)
        assert np.array_equal(pts, result.control_points)
    if "control_mesh.obj" in names:
        assert np.allclose(load_mesh(out / "control_mesh.obj").vertices, result.control_mesh.vertices)
    exports = {n for n in names - CORE - hidden}
    if kind in EXPORTS and exports:
        assert exports == EXPORTS[kind], f"half the exports: {sorted(exports)}"
    return "complete"


def _fires(rng: np.random.Generator, n: int, upto: float) -> list[float]:
    return sorted(float(t) for t in rng.uniform(0.3, upto, size=n))


_rng = np.random.default_rng(1414)
CASES = [(kind, sig, round(t, 2)) for kind, upto in (("curve", 9.0), ("surface", 25.0))
         for sig, t in zip(("INT", "INT2", "TERM", "KILL"), _fires(_rng, 4, upto))]
CASES += [(kind, sig, "writing the exports") for kind in ("curve", "surface") for sig in ("INT", "KILL")]
CASES += [("curve", "INT2", "drawing report.png"), ("surface", "TERM", "search done")]


@pytest.mark.parametrize("kind,sig,when", CASES, ids=[f"{k}-{s}-{w}" for k, s, w in CASES])
def test_signal_leaves_complete_or_untouched_out(tmp_path, kind, sig, when):
    out = tmp_path / "out"
    run = Watched(_argv(kind, tmp_path, out), tmp_path)
    if isinstance(when, str):
        assert run.wait_for(when), "".join(run.err)
    else:
        time.sleep(when)
    sent = time.monotonic()
    if run.proc.poll() is None:
        run.proc.send_signal({"INT": signal.SIGINT, "INT2": signal.SIGINT, "TERM": signal.SIGTERM,
                              "KILL": signal.SIGKILL}[sig])
        if sig == "INT2":
            time.sleep(0.3)
            if run.proc.poll() is None:
                run.proc.send_signal(signal.SIGINT)
    run.finish()
    took = time.monotonic() - sent
    err = "".join(run.err)
    assert "Traceback" not in err and "internal error" not in err, err
    state = _check_out(out, kind, killed=sig == "KILL")
    if sig != "KILL":
        assert took < STOP_SECONDS, f"took {took:.1f} s to stop\n{err}"
        assert run.proc.returncode in (0, 130), err
        if run.proc.returncode == 130:
            assert err.count("error: ") == 1
    if sig != "KILL" and "stopping..." in err and state == "complete" and run.proc.returncode == 0:
        assert "interrupted" in run.out or "done" in run.out
    if sig == "KILL":  # the next run into the same OUT cleans what the killed one left
        get_sample("bspline_05").write(tmp_path / "c2.csv")
        rerun = gsr(["curve", tmp_path / "c2.csv", "-o", out, *TINY_CURVE], tmp_path)
        assert_clean(rerun)
        assert rerun.code == 0
        assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_second_ctrl_c_still_leaves_a_result(tmp_path):
    """Two Ctrl-C in the search: the best so far is still written (not an empty folder)."""
    out = tmp_path / "out"
    # threshold 0 keeps the search running; the checkpoint appears once a generation is done, so there is a
    # best so far to keep however slow the machine is
    checkpoint = tmp_path / "search.ckpt"
    run = Watched([*_argv("surface", tmp_path, out), "--generations", "200", "--threshold", "0",
                   "--checkpoint", checkpoint], tmp_path)
    end = time.monotonic() + 120.0
    while not checkpoint.exists() and run.proc.poll() is None and time.monotonic() < end:
        time.sleep(0.05)
    assert checkpoint.exists(), "".join(run.err)
    run.proc.send_signal(signal.SIGINT)
    time.sleep(0.2)
    run.proc.send_signal(signal.SIGINT)
    run.finish()
    err = "".join(run.err)
    assert "stopping..." in err and "Traceback" not in err
    assert _check_out(out, "surface", killed=False) == "complete", err
    assert Result.load(out / "result.json").interrupted


def test_max_seconds_is_a_hard_cap(tmp_path):
    """--max-seconds bounds the whole reconstruction (search, polish, rewrite), not just the generations."""
    out = tmp_path / "out"
    run = gsr([*_argv("surface", tmp_path, out), "--generations", "200", "--threshold", "0", "--max-seconds", "3",
               "--formats", "none", "--quiet"], tmp_path)  # threshold 0: the protrusion start finds this target at once
    assert_clean(run)
    assert run.code == 0, run.describe()
    result = Result.load(out / "result.json")
    assert result.metrics["stop_reason"] == "max_seconds" and not result.interrupted
    assert result.metrics["seconds"] < 3 + 2.5, result.metrics["seconds"]


def test_ctrl_c_with_a_process_pool(tmp_path):
    """--workers 2: Ctrl-C stops the pool's batch too; the best so far is kept."""
    out = tmp_path / "out"
    run = Watched([*_argv("surface", tmp_path, out), "--workers", "2", "--formats", "none"], tmp_path)
    time.sleep(5.0)
    sent = time.monotonic()
    run.proc.send_signal(signal.SIGINT)
    run.finish()
    assert time.monotonic() - sent < STOP_SECONDS, "".join(run.err)
    err = "".join(run.err)
    assert "Traceback" not in err and run.proc.returncode in (0, 130), err
    assert _check_out(out, "surface", killed=False) in ("complete", "untouched")


def test_a_ctrl_c_that_lands_in_a_finalizer_still_stops_the_command(capfd):
    """A signal whose KeyboardInterrupt is raised inside ``__del__`` (Python swallows it there and prints a
    traceback) reaches the command's own code instead."""
    from gsr_cad.cli import signals

    class Finalized:
        def __del__(self):
            signal.raise_signal(signal.SIGINT)

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with pytest.raises(KeyboardInterrupt):
            with signals.handled():
                Finalized()  # dropped at once: the signal's KeyboardInterrupt is raised in its __del__
                for _ in range(200):
                    time.sleep(0.005)
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
    assert "Traceback" not in capfd.readouterr().err
