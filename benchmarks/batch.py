"""Batch speed-up: the same set of targets through ``gsr batch`` on a LocalCluster of 1 and of 2 workers.

Each run starts its own cluster (its start-up counts: that is what a user waits for). The targets are the
bundled curve samples (and, with ``--surfaces``, surface samples) with a fixed small GA size, so the
figure measures the batch machinery and the parallelism, not one long search. On a shared machine the
timings are noisy: the load average at the start is printed with them.

    python benchmarks/batch.py [--targets 8] [--workers 1,2] [--generations 30] [--surfaces]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import command, environment, load_average, markdown_table

from gsr_cad.reconstruct.samples import all_samples, get_sample


def _targets(d: Path, count: int, surfaces: bool) -> list[str]:
    names = [n for n, info in all_samples().items() if info.kind == "curve" or (surfaces and info.kind == "surface")]
    files = []
    for i in range(count):
        name = names[i % len(names)]
        path = d / f"{i:02d}-{name}{'.csv' if all_samples()[name].kind == 'curve' else '.obj'}"
        get_sample(name).write(path)
        files.append(path.name)
    return files


def _batch(d: Path, files: list[str], workers: int, generations: int) -> tuple[float, str]:
    out = d / f"out-{workers}"
    argv = [sys.executable, "-m", "gsr_cad", "batch", *files, "-o", str(out), "--workers", str(workers),
            "--seed", "1", "--quiet", "--set", f"generations={generations}", "--set", "curve.stall-generations=0",
            "--set", "surface.population=20", "--set", "surface.initial-population=20"]
    started = time.perf_counter()
    proc = subprocess.run(argv, cwd=d, capture_output=True, text=True)
    seconds = time.perf_counter() - started
    if proc.returncode != 0:
        raise SystemExit(f"batch with {workers} workers failed:\n{proc.stdout}\n{proc.stderr}")
    return seconds, proc.stdout.strip().splitlines()[-1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=8)
    parser.add_argument("--workers", default="1,2", help="comma-separated worker counts (default 1,2)")
    parser.add_argument("--generations", type=int, default=30)
    parser.add_argument("--surfaces", action="store_true", help="mix surface samples in")
    args = parser.parse_args(argv)
    counts = [int(w) for w in args.workers.split(",")]
    load = load_average()
    rows = []
    with tempfile.TemporaryDirectory(prefix="gsr-batch-bench-") as tmp:
        d = Path(tmp)
        files = _targets(d, args.targets, args.surfaces)
        base = None
        for workers in counts:
            seconds, summary = _batch(d, files, workers, args.generations)
            base = base or seconds
            rows.append([str(workers), str(len(files)), f"{seconds:.1f}", f"{base / seconds:.2f}x"])
            print(f"{workers} worker(s): {seconds:.1f} s ({summary})", file=sys.stderr)
    print(f"{environment(load)}\n\n{command('batch.py', argv if argv is not None else sys.argv[1:])}\n")
    print("\n".join(markdown_table(["workers", "targets", "seconds", "speed-up"], rows,
                                   {"workers", "targets", "seconds", "speed-up"})))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
