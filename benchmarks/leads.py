"""Which real targets get a body-and-legs start (gsr_cad.reconstruct.leads), and what its gate measured.

Per target: the leads found on its voxel solid, the body's box split twice and the cage with its legs, each
fitted as the gate fits them, their gain (log distance per log control vertices) and whether the refinement's
second path starts from the legs. The targets are the real-data benchmark's (``real_data.py``: pymeshlab's meshes,
OpenSCAD's examples, FreeCAD's IDF parts), or the files given.

    python benchmarks/leads.py [PART.stl ...]
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
from gsr_cad.reconstruct.leads import lead_start
from gsr_cad.reconstruct.surface import REFINE_POINTS, SEARCH_POINTS, SurfaceProblem, _TARGET_SEED, place_template


def row(path: Path) -> str:
    """One table row: the gate's figures on ``path`` as the refinement's grower sees it."""
    started = time.perf_counter()
    config = SurfaceConfig()
    target = surface_target(path)
    template = place_template("cube", target.subsampled(SEARCH_POINTS, _TARGET_SEED), config).mesh
    grower = SurfaceProblem(target, dataclasses.replace(config, max_target_points=REFINE_POINTS), template,
                            exact_back=target.faces is not None, exact_facets=True)
    grower.max_faces = config.refine_max_faces
    found = lead_start(grower)
    seconds = time.perf_counter() - started
    if found is None:
        return f"| {path.name} | - | - | - | - | - | {seconds:.1f} |"
    i = found[1]
    return (f"| {path.name} | {i['leads']} | {i['body_vertices']}: {i['body_distance']:.2e} "
            f"| {i['lead_vertices']}: {i['lead_distance']:.2e} | {i['gain']:.2f} | {'yes' if i['kept'] else 'no'} "
            f"| {seconds:.1f} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", type=Path)
    args = ap.parse_args(argv)
    print("| target | leads | body box (V: distance) | with legs | gain | legs grown | s |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        paths = args.parts or targets(Path(tmp)) + freecad_parts(Path(tmp))
        for path in paths:
            print(row(path), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
