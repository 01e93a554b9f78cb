"""``gsr replay OUT/result.json -o DIR [--formats ...] [--fcstd F.FCStd] [--blend F.blend]``: rebuild and re-export.

The ops are the source of truth: the genome is replayed on the template stored in result.json, so an
edited op gives new control geometry in every export (and in DIR/result.json, control_points.csv or
control_mesh.obj); stored control geometry that disagrees with the replay is reported on stderr
("note: ...") and replaced. An op that no longer applies is an error naming it. ``--fcstd``/``--blend``
also save the host's own document, made by running the exported script in FreeCAD or Blender.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..atomic import write_text
from ..errors import InputError
from ..reconstruct.export import save_document
from ..reconstruct.result import Result
from ._common import parse_formats, prepare_out_dir, write_control_points, write_exports


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="rebuild a saved result.json from its genome and re-export it (no new run)",
                       description=__doc__.splitlines()[0])
    p.add_argument("result", help="result.json, or the directory holding it")
    p.add_argument("-o", "--out", required=True, help="output directory")
    p.add_argument("--formats", help="comma-separated export formats (default: all installed); 'none' for none")
    p.add_argument("--fcstd", metavar="FILE.FCStd", help="also save the FreeCAD document (runs freecadcmd)")
    p.add_argument("--blend", metavar="FILE.blend", help="also save the Blender file (runs blender -b)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    source = Path(args.result)
    source = source / "result.json" if source.is_dir() else source
    result = Result.load(source)
    for note in result.notes:
        print(f"note: {note}", file=sys.stderr)
    formats = parse_formats(args.formats, result.kind)
    documents = [(flag, Path(path)) for flag, path in (("--fcstd", args.fcstd), ("--blend", args.blend)) if path]
    for flag, path in documents:
        if path.suffix.lower() != flag.replace("--", ".").lower():
            raise InputError(f"{flag} needs a file name ending in {flag.replace('--', '.')}, got {path.name}")
    out = prepare_out_dir(args.out)
    written = write_exports(result, out, formats)
    written += [save_document(result, path) for _, path in documents]
    if result.kind == "curve":
        written.append(write_control_points(out / "control_points.csv", result.control_points))
    else:
        from ..reconstruct.meshio import save_obj

        written.append(save_obj(result.control_mesh, out / "control_mesh.obj"))
    target = out / "result.json"
    text = json.dumps(result.to_json(), indent=1) + "\n"
    if not (target.is_file() and target.read_text(encoding="utf-8") == text):
        written.append(write_text(target, text))
    for path in written:
        print(f"wrote {path}")
    return 0
