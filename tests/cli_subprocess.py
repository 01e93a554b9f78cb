"""Run the real ``gsr`` CLI in a subprocess (as a user would), with a timeout, and judge its stderr."""

from __future__ import annotations

import atexit
import contextlib
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

TINY_CURVE = ("--generations", "2", "--population", "4", "--initial-population", "8", "--formats", "none",
              "--quiet")
"""Settings that make a curve run take well under a second."""
TINY_SURFACE = ("--generations", "1", "--population", "4", "--initial-population", "4", "--n-parents", "2",
                "--max-children", "1", "--n-perturb", "1", "--n-newcomers", "1", "--polish-rounds", "0",
                "--final-polish-rounds", "1", "--no-simplify-history", "--refine-max-faces", "24",
                "--refine-seconds", "5", "--refine-points", "3000",
                "--formats", "none", "--quiet")
"""Settings that make a surface run short: a small search, and a refinement bounded by faces and by seconds (a
tetrahedron's sharp corners never reach the refinement's goal: its 40-face growth took 40-100 s in its default
300 s, past the fuzz cases' 120 s timeout when two ran side by side; with 40 faces and 10 s, fuzz cases took up to
23 s)."""


@dataclasses.dataclass
class Run:
    argv: list[str]
    code: int | None
    out: str
    err: str
    seconds: float
    timed_out: bool = False

    @property
    def err_lines(self) -> list[str]:
        return [line for line in self.err.replace("\r", "\n").splitlines() if line.strip()]

    def describe(self) -> str:
        return f"gsr {' '.join(self.argv)} -> exit {self.code}\nstdout: {self.out[-800:]}\nstderr: {self.err[-1500:]}"


def env() -> dict[str, str]:
    e = dict(os.environ)
    e.pop("GSR_DEBUG", None)
    e["PYTHONWARNINGS"] = ""
    e["COLUMNS"] = "100"
    return e


def popen(argv: Sequence[str], cwd: Path, preexec: Callable[[], None] | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "gsr_cad", *map(str, argv)], cwd=cwd, env=env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
                            preexec_fn=preexec)


def gsr(argv: Sequence[str], cwd: Path, timeout: float = 90.0, preexec: Callable[[], None] | None = None) -> Run:
    """Run ``gsr argv`` to the end (killed after ``timeout`` seconds: a hang)."""
    started = time.monotonic()
    proc = popen(argv, cwd, preexec)
    try:
        out, err = proc.communicate(timeout=timeout)
        return Run(list(map(str, argv)), proc.returncode, out, err, time.monotonic() - started)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        out, err = proc.communicate()
        return Run(list(map(str, argv)), None, out, err, time.monotonic() - started, timed_out=True)


def assert_clean_error(run: Run) -> None:
    """Bad input: exit 2, exactly one ``error:`` line on stderr and nothing else there."""
    assert not run.timed_out, "hang: " + run.describe()
    assert "Traceback" not in run.err, run.describe()
    assert run.code == 2, run.describe()
    assert len(run.err_lines) == 1 and run.err_lines[0].startswith("error: "), run.describe()
    assert "internal error" not in run.err, run.describe()


def assert_clean(run: Run) -> None:
    """Any input: it finishes (no hang), without a traceback or an internal error; a failure is exactly one
    ``error:`` line with exit 2; a success leaves only ``warning:`` lines on stderr (no numpy warnings)."""
    assert not run.timed_out, "hang: " + run.describe()
    assert "Traceback" not in run.err and "internal error" not in run.err, run.describe()
    if run.code == 0:
        assert all(line.startswith("warning: ") for line in run.err_lines), run.describe()
    else:
        assert_clean_error(run)


_AS_NOBODY = """
import os, sys
from gsr_cad.cli import build_parser, main
build_parser()
os.setgid(65534)
os.setuid(65534)
sys.exit(main(sys.argv[1:]))
"""


def gsr_as_nobody(argv: Sequence[str], cwd: Path, timeout: float = 90.0) -> Run:
    """Run ``gsr argv`` as user 'nobody' (the modules are imported first, as root: the interpreter may live in
    a directory 'nobody' cannot read). Needs root."""
    started = time.monotonic()
    proc = subprocess.run([sys.executable, "-c", _AS_NOBODY, *map(str, argv)], cwd=cwd, env=env(),
                          capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    return Run(list(map(str, argv)), proc.returncode, proc.stdout, proc.stderr, time.monotonic() - started)


_FORK_SERVER = r"""
import json, os, sys, traceback
from gsr_cad.cli import build_parser, main
build_parser()  # every subcommand imported once, here
for line in sys.stdin:
    req = json.loads(line)
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.chdir(req["cwd"])
            os.environ.clear()
            os.environ.update(req["env"])
            os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
            for fd, path in ((1, req["out"]), (2, req["err"])):
                os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600), fd)
            sys.argv = ["gsr", *req["argv"]]
            code = main()
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        except BaseException:
            traceback.print_exc()
        finally:
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except Exception:
                    pass
            os._exit(code)
    print(pid, flush=True)
    _, status = os.waitpid(pid, 0)
    print(os.waitstatus_to_exitcode(status), flush=True)
"""


class _ForkServer:
    """A process that has imported ``gsr_cad`` once and forks a fresh process for each CLI run: the run is the
    real ``main`` in a process of its own (its exit code, stdout, stderr, a hang killed), without the second of
    imports each ``python -m gsr_cad`` start takes (over the fuzz corpus's 220 cases, minutes of the suite)."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", _FORK_SERVER], env=env(), stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, bufsize=1)
        self.folder = Path(tempfile.mkdtemp(prefix="gsr-forked-"))  # the runs' stdout and stderr, outside their cwd
        atexit.register(self.close)

    def close(self) -> None:
        """End the server (its input closed, it leaves its loop) and remove its folder."""
        with contextlib.suppress(OSError, ValueError, subprocess.TimeoutExpired):
            if self.proc.stdin is not None:
                self.proc.stdin.close()
            self.proc.wait(timeout=10)
        shutil.rmtree(self.folder, ignore_errors=True)

    def run(self, argv: Sequence[str], cwd: Path, timeout: float) -> Run:
        started = time.monotonic()
        out, err = self.folder / "stdout", self.folder / "stderr"
        request = {"argv": list(map(str, argv)), "cwd": str(cwd), "env": env(), "out": str(out), "err": str(err)}
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps(request) + "\n")
        self.proc.stdin.flush()
        pid = int(self.proc.stdout.readline())
        timer = threading.Timer(timeout, os.kill, (pid, signal.SIGKILL))
        timer.start()
        try:
            code = int(self.proc.stdout.readline())
        finally:
            timer.cancel()
        seconds = time.monotonic() - started
        timed_out = code == -signal.SIGKILL and seconds >= timeout
        texts = [p.read_text(errors="replace") for p in (out, err)]
        for p in (out, err):
            p.unlink()
        return Run(list(map(str, argv)), None if timed_out else code, texts[0], texts[1], seconds, timed_out)


_SERVER: _ForkServer | None = None


def gsr_forked(argv: Sequence[str], cwd: Path, timeout: float = 90.0) -> Run:
    """``gsr argv`` as :func:`gsr` runs it, but in a process forked from one that has imported gsr_cad already
    (:class:`_ForkServer`; ``python -m gsr_cad``'s own start is exercised by :func:`gsr`'s callers)."""
    global _SERVER
    if _SERVER is None or _SERVER.proc.poll() is not None:
        _SERVER = _ForkServer()
    return _SERVER.run(argv, cwd, timeout)
