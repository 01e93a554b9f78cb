"""Huge inputs: 10^6-point curves and clouds through the ``gsr`` CLI, wall time and peak memory of the whole run.

Inputs, made from the bundled samples (:mod:`gsr_cad.reconstruct.samples`) and written as text files, as a
user would have them:

* ``open curve``: 10^6 points on the cubic B-spline of ``bspline_09``'s true control polygon;
* ``closed curve``: 10^6 points on the periodic cubic B-spline of the same polygon;
* ``cloud <sample>``: 10^6 points drawn by area on the exact limit surface of a surface sample's true
  control mesh (``extended``, ``inset_extrude``).

Each runs as its own ``gsr curve`` / ``gsr surface`` process with default settings, ``--formats none`` and
``--quiet``; surfaces with the search budget ``--max-seconds`` (default 30, a hard cap on search, polish
and history rewrite; the final distances over all points come after it). Peak memory is the run's
maximum resident set size (GNU ``time``, else ``wait4``). The target is met when the whole run takes under 60 s and 2 GB.
Distances are both ways, over every input point, in % of the bounding-box diagonal (from result.json). On
a shared machine the timings are noisy: the load average at the start is printed with them.

    python benchmarks/huge.py [--points 1000000] [--max-seconds 30] [--only curve|surface]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from gsr_cad.atomic import write_text

sys.path.insert(0, str(Path(__file__).resolve().parent))  # _common, also when this file is loaded by path
from _common import command, environment, load_average, markdown_table  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "huge.md"
SECONDS_GOAL, MB_GOAL = 60.0, 2048.0
CLOUD_SAMPLES = ("extended", "inset_extrude")


def _write(path: Path, points: np.ndarray, header: str) -> Path:
    np.savetxt(path, points, fmt="%.10g", delimiter="," if path.suffix == ".csv" else " ", header=header,
               comments="")
    return path


def make_inputs(d: Path, n: int, only: str | None) -> list[tuple[str, str, Path]]:
    """``(label, kind, file)`` of the huge inputs, written into ``d``."""
    from gsr_cad.geometry.bspline import make_spline
    from gsr_cad.geometry.limit_surface import LimitSurface
    from gsr_cad.reconstruct.samples import get_sample

    out = []
    if only in (None, "curve"):
        ctrl = np.asarray(get_sample("bspline_09").truth_ctrl)
        out.append(("open curve (bspline_09)", "curve",
                    _write(d / "open.csv", make_spline(ctrl, 3, False)(np.linspace(0.0, 1.0, n)), "x,y")))
        out.append(("closed curve (bspline_09, periodic)", "curve",
                    _write(d / "closed.csv", make_spline(ctrl, 3, True)(np.arange(n) / n), "x,y")))
    if only in (None, "surface"):
        for name in CLOUD_SAMPLES:
            cloud = LimitSurface.of(get_sample(name).truth_control).random_points(n, 7)
            out.append((f"cloud ({name})", "surface", _write(d / f"{name}.xyz", cloud, "")))
    return out


def run(kind: str, path: Path, out: Path, max_seconds: float, timeout: float) -> tuple[int, float, float]:
    """Exit code, wall seconds and peak resident MB of one ``gsr`` run.

    Linux carries a parent's peak over into a forked child's, so the peak is read by GNU ``time`` (a small
    parent) where it is installed, else from ``wait4`` (then it includes this script's own, which is small
    too: the inputs are made in a child process)."""
    argv = [sys.executable, "-m", "gsr_cad", kind, str(path), "-o", str(out), "--quiet", "--formats", "none",
            "--seed", "1"]
    if kind == "surface":
        argv += ["--max-seconds", f"{max_seconds:g}"]
    gnu_time = Path("/usr/bin/time")
    peak_file = out.with_suffix(".peak")
    if gnu_time.is_file():
        argv = [str(gnu_time), "-f", "%M", "-o", str(peak_file), *argv]
    started = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = started + timeout
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.perf_counter() > deadline:
            proc.kill()
            pid, status, usage = os.wait4(proc.pid, 0)
            break
        time.sleep(0.05)
    seconds = time.perf_counter() - started
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace").strip() if proc.stderr else ""
    if proc.returncode not in (0, 3):
        print(f"{kind} {path.name}: exit {proc.returncode}: {err[-500:]}", file=sys.stderr)
    peak_kb = float(usage.ru_maxrss)
    if peak_file.is_file():
        lines = peak_file.read_text().split()
        peak_kb = float(lines[-1]) if lines and lines[-1].isdigit() else peak_kb
    return proc.returncode, seconds, peak_kb / 1024.0


def _pct(x: object) -> str:
    return f"{100.0 * float(x):.2g}" if isinstance(x, (int, float)) else "-"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--max-seconds", type=float, default=30.0, help="surface search budget (default 30)")
    parser.add_argument("--timeout", type=float, default=300.0, help="kill a run after this many seconds")
    parser.add_argument("--only", choices=("curve", "surface"), help="only curves or only clouds")
    parser.add_argument("--no-write", action="store_true", help=f"do not write {RESULTS.name}")
    parser.add_argument("--make", metavar="DIR", help=argparse.SUPPRESS)  # the child that writes the inputs
    args = parser.parse_args(argv)
    if args.make:
        print(json.dumps([(label, kind, path.name) for label, kind, path in
                          make_inputs(Path(args.make), args.points, args.only)]))
        return 0
    load = load_average()
    header = ["input", "points", "budget", "seconds", "peak MB", "data->fit mean %", "data->fit max %",
              "fit->data mean %", "fit->data max %", "search points", "metric points", "met?"]
    rows = []
    with tempfile.TemporaryDirectory(prefix="gsr-huge-") as tmp:
        d = Path(tmp)
        made = subprocess.run([sys.executable, __file__, "--make", tmp, "--points", str(args.points),
                               *(["--only", args.only] if args.only else [])], check=True, capture_output=True,
                              text=True)
        for label, kind, name in json.loads(made.stdout):
            path = d / name
            out = d / f"out-{path.stem}"
            code, seconds, mb = run(kind, path, out, args.max_seconds, args.timeout)
            m, n_target = {}, "-"
            if (out / "result.json").is_file():
                saved = json.loads((out / "result.json").read_text())
                m, n_target = saved["metrics"], saved["config"].get("target", {}).get("n_points", "-")
            met = code in (0, 3) and seconds < SECONDS_GOAL and mb < MB_GOAL
            budget = "default" if kind == "curve" else f"--max-seconds {args.max_seconds:g}"
            rows.append([label, f"{args.points:,}", budget, f"{seconds:.1f}", f"{mb:.0f}",
                         _pct(m.get("data_to_fit_mean")), _pct(m.get("data_to_fit_max")),
                         _pct(m.get("fit_to_data_mean")), _pct(m.get("fit_to_data_max")),
                         f"{m.get('n_search_points', m.get('search_points', '-'))}",
                         f"{m.get('n_data_samples', n_target)}",
                         "yes" if met else f"no (exit {code})" if code not in (0, 3) else "no"])
            print(" | ".join(rows[-1]), file=sys.stderr)
    table = markdown_table(header, rows, set(header) - {"input", "budget", "met?"})
    text = "\n".join([
        "# Huge inputs (10^6 points through the CLI)", "",
        f"Goal: the whole `gsr curve` / `gsr surface` run under {SECONDS_GOAL:.0f} s and {MB_GOAL / 1024:.0f} GB "
        "(peak resident memory of the process).", "",
        f"{environment(load)}", "",
        command("huge.py", argv if argv is not None else sys.argv[1:]), "", *table, ""])
    print(text)
    if not args.no_write:
        write_text(RESULTS, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
