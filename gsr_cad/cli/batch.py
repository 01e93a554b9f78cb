"""``gsr batch INPUTS... -o DIR``: reconstruct many targets on a dask.distributed cluster.

Each target runs as its own ``gsr curve`` or ``gsr surface`` process (chosen from the file: meshes and
3-column data are surfaces, 2-column data curves) on a cluster worker, writing ``DIR/<name>/``; a failing
target fails alone. Without ``--scheduler`` a LocalCluster of ``--workers`` single-threaded processes runs
here; with it, the workers of that cluster (which must see the same paths). One line is printed per target
as it finishes, with the overall count (a surface's refinement runs on one process, as the cluster's workers share
the CPUs, unless ``--set refine_workers=...`` says otherwise); ``DIR/summary.csv`` and ``DIR/summary.md`` (target,
kind, distances both ways, controls, ops, seconds, status) are rewritten after each. Running the same batch again
skips the targets whose ``result.json`` is complete (a stopped batch resumes); Ctrl-C stops the batch, keeping what
is done.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from ..atomic import write_text
from ..errors import ConfigError, GsrError, InputError
from ..reconstruct.inputs import open_input, target_kind
from ._common import check_seed, prepare_out_dir, whole_number

MAX_WORKERS = 256
COLUMNS = ("target", "kind", "status", "data_to_fit_mean", "data_to_fit_max", "fit_to_data_mean", "fit_to_data_max",
           "controls", "ops", "seconds", "out", "error")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("batch", help="reconstruct many targets on dask.distributed, with a summary table",
                       description=__doc__.splitlines()[0])
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="target files (curves and surfaces may be mixed)")
    p.add_argument("-o", "--out", required=True, help="output directory (one sub-directory per target)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="dask scheduler address (default: a LocalCluster here)")
    p.add_argument("--workers", type=whole_number, default=None,
                   help=f"LocalCluster worker processes (default: the CPU count, at most {MAX_WORKERS})")
    p.add_argument("--preset", choices=("default", "paper"), default="default", help="preset of every run")
    p.add_argument("--seed", type=whole_number, default=None, help="random seed of every run")
    p.add_argument("--formats", default="none", help="export formats of every run (default none)")
    p.add_argument("--set", action="append", default=[], metavar="[KIND.]FIELD=VALUE",
                   help="a setting for every run, or only the curve or surface runs, e.g. --set generations=20 "
                        "--set surface.population=20 (repeatable)")
    p.add_argument("--timeout", type=float, default=0.0,
                   help="seconds after which a target's run is stopped (0: none); it then keeps its best so far")
    p.add_argument("--quiet", action="store_true", help="no per-target lines")
    p.set_defaults(run=run)


def _settings(pairs: list[str], kind: str) -> list[str]:
    """The ``[KIND.]FIELD=VALUE`` pairs that apply to ``kind`` as command-line flags (the values are checked
    by each run's own parser)."""
    flags = []
    for pair in pairs:
        field, sep, value = pair.partition("=")
        scope, dot, name = field.strip().rpartition(".")
        if not sep or not name or not name.replace("_", "").replace("-", "").isalnum() or \
                (dot and scope not in ("curve", "surface")):
            raise InputError(f"--set expects [curve.|surface.]FIELD=VALUE, not {pair!r}")
        if not dot or scope == kind:  # FIELD= (no value) is a switch such as no-simplify-history
            flags += ["--" + name.replace("_", "-")] + ([value.strip()] if value.strip() else [])
    return flags


def _out_names(inputs: list[str]) -> list[str]:
    """One output sub-directory name per input: its stem, made unique by a ``-2``, ``-3`` ... suffix."""
    names, seen = [], {}
    for path in inputs:
        stem = "".join(c if c.isalnum() or c in "-_." else "_" for c in Path(path).stem) or "target"
        seen[stem] = seen.get(stem, 0) + 1
        names.append(stem if seen[stem] == 1 else f"{stem}-{seen[stem]}")
    return names


def _complete(out: Path) -> dict[str, Any] | None:
    """The metrics of a finished (not interrupted) result in ``out``, else None."""
    from ..reconstruct.result import Result

    if not (out / "result.json").is_file():
        return None
    try:
        result = Result.load(out / "result.json")
    except GsrError:
        return None
    return None if result.interrupted else {"kind": result.kind, "metrics": result.metrics}


def _stop_with_parent() -> None:
    """In the child, before exec: on Linux, get SIGTERM (= Ctrl-C: keep the best so far) if the worker that
    started it dies, so that a stopped batch leaves no run behind."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def run_target(path: str, kind: str, out: str, flags: list[str], timeout: float) -> dict[str, Any]:
    """Run one target as a ``gsr`` process (on a cluster worker); returns its summary row."""
    started = time.perf_counter()
    cmd = [sys.executable, "-m", "gsr_cad", kind, path, "-o", out, "--quiet", *flags]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL,
                            preexec_fn=_stop_with_parent if sys.platform.startswith("linux") else None)
    try:
        stdout, stderr = proc.communicate(timeout=timeout or None)
    except subprocess.TimeoutExpired:
        proc.terminate()  # SIGTERM = Ctrl-C: the run keeps its best so far
        try:
            stdout, stderr = proc.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            stdout, stderr = proc.communicate()
    errors = [line[len("error: "):] for line in stderr.splitlines() if line.startswith("error: ")]
    row: dict[str, Any] = {"target": path, "kind": kind, "out": out, "seconds": time.perf_counter() - started,
                           "returncode": proc.returncode}
    done = _complete(Path(out))
    if proc.returncode in (0, 3) and done is not None:
        row["status"] = "done" if proc.returncode == 0 else "tolerance missed"
        row.update(_metric_columns(done["metrics"]))
    elif proc.returncode in (0, 3):
        row["status"] = "stopped"
    else:
        row["status"] = "failed"
        row["error"] = errors[0] if errors else f"exit code {proc.returncode}"
    return row


def _metric_columns(m: dict[str, Any]) -> dict[str, Any]:
    """The summary columns of a result's metrics (two-sided distances when present, else mean/max)."""
    row = {key: m.get(key) for key in ("data_to_fit_mean", "data_to_fit_max", "fit_to_data_mean", "fit_to_data_max")}
    if row["data_to_fit_mean"] is None:
        row["data_to_fit_mean"], row["data_to_fit_max"] = m.get("mean_distance"), m.get("max_distance")
    row["controls"] = m.get("n_control_points", m.get("n_control_vertices"))
    row["ops"] = m.get("n_ops")
    if m.get("seconds") is not None:
        row["seconds"] = m["seconds"]
    return row


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else str(value)
    return str(value)


def write_summary(out: Path, rows: list[dict[str, Any]]) -> tuple[Path, Path]:
    """``summary.csv`` and ``summary.md`` of the rows (in input order), both written atomically."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in COLUMNS])
    md = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    md += ["| " + " | ".join(_cell(row.get(c)).replace("|", "\\|") for c in COLUMNS) + " |" for row in rows]
    return (write_text(out / "summary.csv", buf.getvalue()), write_text(out / "summary.md", "\n".join(md) + "\n"))


def _client(args: argparse.Namespace):
    try:
        from dask import distributed
    except ImportError:
        raise ConfigError("gsr batch needs dask.distributed: pip install 'gsr-cad[dask]'") from None
    if args.scheduler:
        try:
            return distributed.Client(args.scheduler, timeout=30), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot reach the dask scheduler {args.scheduler}: {exc}") from None
    workers = args.workers or os.cpu_count() or 1
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=50)
    return distributed.Client(cluster), cluster


def run(args: argparse.Namespace) -> int:
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        raise ConfigError(f"--workers must lie in [1, {MAX_WORKERS}], not {args.workers}")
    if not (math.isfinite(args.timeout) and 0 <= args.timeout <= 2_592_000):
        raise ConfigError(f"--timeout must lie in [0, 2592000] seconds, not {args.timeout}")
    check_seed(args.seed)
    common = ["--preset", args.preset, "--formats", args.formats]
    if args.seed is not None:
        common += ["--seed", str(args.seed)]
    flags = {kind: common + _settings(args.set, kind) for kind in ("curve", "surface")}
    if "--refine-workers" not in flags["surface"]:  # the cluster's workers share the CPUs: one process each
        flags["surface"] += ["--refine-workers", "1"]
    kinds = []
    for path in args.inputs:
        open_input(path, "target file")
        kinds.append(target_kind(path))
    out = prepare_out_dir(args.out, names=("summary.csv", "summary.md"))
    names = _out_names(args.inputs)
    rows: list[dict[str, Any]] = [{"target": p, "kind": k, "status": "pending", "out": str(out / n)}
                                  for p, k, n in zip(args.inputs, kinds, names)]
    todo = []
    for i, row in enumerate(rows):
        done = _complete(Path(row["out"]))
        if done is not None and done["kind"] == row["kind"]:
            row.update(_metric_columns(done["metrics"]), status="done (earlier run)")
        else:
            todo.append(i)
    started = time.perf_counter()
    finished = len(rows) - len(todo)
    if not args.quiet and finished:
        print(f"skipping {finished} target(s) already done in {out}")
    write_summary(out, rows)
    if todo:
        finished = _run_all(args, rows, todo, flags, out, finished)
    failed = sum(r["status"] == "failed" for r in rows)
    csv_path, md_path = write_summary(out, rows)
    print(f"batch: {finished}/{len(rows)} targets finished, {failed} failed, "
          f"{time.perf_counter() - started:.1f} s -> {csv_path}, {md_path.name}")
    return 0 if not failed else (2 if failed == len(rows) else 1)


def _run_all(args: argparse.Namespace, rows: list[dict[str, Any]], todo: list[int], flags: dict[str, list[str]],
             out: Path,
             finished: int) -> int:
    from dask import distributed

    client, cluster = _client(args)
    try:
        futures = {client.submit(run_target, os.path.abspath(rows[i]["target"]), rows[i]["kind"],
                                 os.path.abspath(rows[i]["out"]), flags[rows[i]["kind"]], args.timeout, pure=False,
                                 key=f"gsr-{i}"): i
                   for i in todo}
        for future in distributed.as_completed(futures):
            i = futures[future]
            try:
                rows[i].update(future.result())
            except Exception as exc:  # a worker that died: that target failed, the batch goes on
                rows[i].update(status="failed", error=f"{type(exc).__name__}: {exc}".splitlines()[0])
            rows[i]["target"] = args.inputs[i]
            finished += 1
            write_summary(out, rows)
            if not args.quiet:
                r = rows[i]
                detail = (f"mean {_cell(r.get('data_to_fit_mean'))}, max {_cell(r.get('data_to_fit_max'))}, "
                          f"{_cell(r.get('controls'))} controls" if r["status"] != "failed" else r.get("error", ""))
                print(f"[{finished}/{len(rows)}] {r['target']} ({r['kind']}): {r['status']}: {detail}, "
                      f"{_cell(r.get('seconds'))} s", flush=True)
    except KeyboardInterrupt:
        print("stopping... (finished targets are kept; run the same batch again to resume)", file=sys.stderr)
        write_summary(out, rows)
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return finished
