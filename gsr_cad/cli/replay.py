"""``gsr replay OUT/result.json -o DIR [--formats ...]``: re-export a saved result without re-running."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ..atomic import write_bytes, write_text
from ..reconstruct.result import Result
from ._common import parse_formats, prepare_out_dir, write_exports


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="re-export a saved result.json in CAD formats (no new run)",
                       description=__doc__.splitlines()[0])
    p.add_argument("result", help="result.json, or the directory holding it")
    p.add_argument("-o", "--out", required=True, help="output directory")
    p.add_argument("--formats", help="comma-separated export formats (default: all installed); 'none' for none")
    p.set_defaults(run=run)


def write_control_points(path: Path, points: np.ndarray) -> Path:
    """``x,y`` CSV of the control points at full double precision (as ``gsr curve`` writes it), atomically."""
    rows = "".join(f"{x:.17g},{y:.17g}\n" for x, y in np.asarray(points, dtype=float))
    return write_text(path, "x,y\n" + rows)


def run(args: argparse.Namespace) -> int:
    source = Path(args.result)
    source = source / "result.json" if source.is_dir() else source
    result = Result.load(source)
    formats = parse_formats(args.formats, result.kind)
    out = prepare_out_dir(args.out)
    written = write_exports(result, out, formats)
    if result.kind == "curve":
        written.append(write_control_points(out / "control_points.csv", result.control_points))
    else:
        from ..reconstruct.meshio import save_obj

        written.append(save_obj(result.control_mesh, out / "control_mesh.obj"))
    target = out / "result.json"
    if not (target.exists() and target.resolve() == source.resolve()):
        written.append(write_bytes(target, source.read_bytes()))
    for path in written:
        print(f"wrote {path}")
    return 0
