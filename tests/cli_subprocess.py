"""Run the real ``gsr`` CLI in a subprocess (as a user would), with a timeout, and judge its stderr."""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

TINY_CURVE = ("--generations", "2", "--population", "4", "--initial-population", "8", "--formats", "none",
              "--quiet")
"""Settings that make a curve run take well under a second."""
TINY_SURFACE = ("--generations", "1", "--population", "4", "--initial-population", "4", "--n-parents", "2",
                "--max-children", "1", "--n-perturb", "1", "--n-newcomers", "1", "--polish-rounds", "0",
                "--final-polish-rounds", "1", "--no-simplify-history", "--refine-max-faces", "24",
                "--refine-seconds", "5",
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
