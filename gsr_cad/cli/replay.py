"""``gsr replay OUT/result.json -o DIR [--formats ...]``: re-export a saved result without re-running."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..atomic import write_bytes
from ..reconstruct.result import Result
from ._common import parse_formats, prepare_out_dir, write_control_points, write_exports


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="re-export a saved result.json in CAD formats (no new run)",
                       description=__doc__.splitlines()[0])
    p.add_argument("result", help="result.json, or the directory holding it")
    p.add_argument("-o", "--out", required=True, help="output directory")
    p.add_argument("--formats", help="comma-separated export formats (default: all installed); 'none' for none")
    p.set_defaults(run=run)


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
