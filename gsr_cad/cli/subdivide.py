"""``gsr subdivide MESH -o OUT.obj``: Catmull-Clark refinement (or limit positions) of a polygon mesh."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import InputError
from ._common import check_output_file, whole_number

DEFAULT_LEVELS = 2
MAX_LEVELS = 64
"""Levels beyond which no mesh fits in memory (each level quadruples the faces); refused before any work."""


def add_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = subparsers.add_parser("subdivide", help="Catmull-Clark subdivide a polygon mesh (OBJ, OFF, PLY, STL)",
                              description=__doc__.splitlines()[0])
    p.add_argument("mesh", metavar="MESH", help="control mesh: .obj, .off or .ply (n-gons kept) or .stl")
    p.add_argument("-o", "--out", dest="output", metavar="OUT",
                   help="refined mesh to write: .obj, .off, .ply (quads) or .stl (triangulated)")
    p.add_argument("--output", dest="output", help=argparse.SUPPRESS)  # the old spelling, kept working
    p.add_argument("--levels", type=whole_number, default=DEFAULT_LEVELS, metavar="K",
                   help=f"subdivision steps (default {DEFAULT_LEVELS})")
    p.add_argument("--limit", action="store_true",
                   help="move every output vertex to its position on the limit surface")
    p.add_argument("--boundary", choices=("all", "corners"), default="all",
                   help="'all' smooths boundary corners too (Blender's default), 'corners' keeps them fixed")
    p.set_defaults(run=run)
    return p


def run(args: argparse.Namespace) -> int:
    from ..geometry.subdivision import CatmullClark
    from ..geometry.validation import mesh_report
    from ..reconstruct.meshio import WRITE_FORMATS, load_mesh, save_mesh

    if not args.output:
        raise InputError("subdivide needs -o OUT (the refined mesh to write)")
    if args.levels > MAX_LEVELS:
        raise InputError(f"--levels must lie in [0, {MAX_LEVELS}], not {args.levels} "
                         "(each level quadruples the faces)")
    out = check_output_file(args.output, "-o")
    if out.suffix.lower().lstrip(".") not in WRITE_FORMATS:
        raise InputError(f"{out.name}: cannot write format {out.suffix or '(no suffix)'!r} "
                         f"(use {', '.join('.' + f for f in WRITE_FORMATS)})")
    if out.is_dir():
        raise InputError(f"{out}: is a directory, give a file name")
    mesh = load_mesh(args.mesh)
    cc = CatmullClark(mesh, args.levels, args.boundary)
    result = cc.limit(mesh.vertices) if args.limit else cc.refine(mesh.vertices)
    save_mesh(result, out)
    report = mesh_report(mesh)
    shape = "closed" if report["closed"] else f"open ({report['boundary_edges']} boundary edges)"
    print(f"read {args.mesh}: {report['vertices']} vertices, {report['faces']} faces, {shape}, "
          f"Euler characteristic {report['euler_characteristic']}")
    what = "limit positions" if args.limit else "refined"
    print(f"wrote {out}: {result.n_vertices} vertices, {result.n_faces} faces "
          f"(level {args.levels}, {what}, boundary {args.boundary})")
    return 0
