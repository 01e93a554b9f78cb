"""Which real targets get a designer's start (gsr_cad.reconstruct.starts: body and legs, body and blocks), and
what its gate measured.

Per target and kind: how many legs or blocks were found on its voxel solid (and grown), the body's box and the
cage with them, each fitted as the gate fits them, their gain (log distance per log control vertices) on that box
and on the template's box split as often, and which start the refinement's second path takes; then the start's
edges along the part's creased (module sharp: how many, and its distance after), and the placed cube's (fitted,
then creased where its faces meet sharply: 8 control vertices before and after). The targets are the
real-data benchmark's (``real_data.py``: pymeshlab's meshes, OpenSCAD's examples, FreeCAD's IDF parts), or the
files given.

    python benchmarks/starts.py [PART.stl ...]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

from real_data import freecad_parts, targets

from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.sharp import sharpened
from gsr_cad.reconstruct.starts import structured_start
from gsr_cad.reconstruct.surface import (FRONT_ROUNDS, SEARCH_POINTS, SurfaceProblem, _TARGET_SEED,
                                         place_template)


def creased_cube(grower) -> str:
    """The placed cube fitted as the front's cages are, then its sharp edges creased (module sharp)."""
    vertices, cost = grower.fit(grower.template, FRONT_ROUNDS)
    sharp = sharpened(grower, grower.template, vertices, cost, FRONT_ROUNDS, coarse=True)
    return f"{cost:.2e} -> " + ("-" if sharp is None else f"{len(sharp[0])} C {sharp[2]:.2e}")


def row(path: Path) -> str:
    """One table row: the gate's figures on ``path`` as the refinement's grower sees it."""
    started = time.perf_counter()
    config = SurfaceConfig()
    target = surface_target(path)
    template = place_template("cube", target.subsampled(SEARCH_POINTS, _TARGET_SEED), config).mesh
    grower = SurfaceProblem(target, dataclasses.replace(config, max_target_points=config.refine_points), template,
                            exact_back=target.faces is not None, exact_facets=True)
    grower.max_faces = config.refine_max_faces
    found = structured_start(grower)
    cube = creased_cube(grower)
    seconds = time.perf_counter() - started
    if found is None:
        return f"| {path.name} | - | - | - | - | - | {cube} | {seconds:.1f} |"
    cells = []
    for kind in ("leads", "blocks"):
        i = found[1][kind]
        on = i and i.get("gain_on_template")
        on = "" if on is None else f", on the template's {on:.2f}"
        cells.append("-" if i is None else
                     f"{i['found']} ({i['grown']}): {i['body_vertices']} V {i['body_distance']:.2e} -> "
                     f"{i['vertices']} V {i['distance']:.2e}, gain {i['gain']:.2f}{on}{' kept' if i['kept'] else ''}")
    box = found[1].get("template_vertices")
    template = "-" if box is None else f"{box} V {found[1]['template_distance']:.2e}"
    creased = (f"{found[1]['creases']} C {found[1]['creased_distance']:.2e}" if found[1].get("creases") else "-")
    return (f"| {path.name} | {cells[0]} | {cells[1]} | {template} | {found[1]['path'] or '-'} | {creased} | {cube} "
            f"| {seconds:.1f} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", type=Path)
    args = ap.parse_args(argv)
    print("| target | leads found (grown): body box -> with legs | blocks found (grown): body box -> with blocks "
          "| template's box | second path starts from | start creased | placed cube: smooth -> creased | s |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        paths = args.parts or targets(Path(tmp)) + freecad_parts(Path(tmp))
        for path in paths:
            print(row(path), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
