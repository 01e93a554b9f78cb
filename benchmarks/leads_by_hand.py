"""A body box with its leads, built by hand from the target, fitted, against the quad-remesh baseline.

The measurement behind the next step for leaded parts (`benchmarks/results/real_data_session24.md`). The body
is the largest piece of the part's voxel solid (trimesh, ``RESOLUTION`` cells along its longest axis) after an
opening by a ball of ``OPENING_SHARE`` of its thinnest extent. The leads are the pieces of the solid outside the
dilated body. The cage is the cube on the body's oriented box, split ``BODY_SPLITS`` times. Per lead it gets an
inset of the face nearest where the lead leaves and facing along it, then ``SEGMENTS`` extrusions along it.
Then it is fitted as the baseline's cages are, split once, and fitted again. Each row is compared with the
baseline at about the same vertex count.

    python benchmarks/leads_by_hand.py PART.stl [PART.stl ...]
"""

from __future__ import annotations

import argparse

import numpy as np
import trimesh
from baseline_quadremesh import baseline, fitted
from scipy import ndimage

from gsr_cad.errors import OpError
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.ops.mesh import Extrude, Inset
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.placement import place_cube
from gsr_cad.reconstruct.refine import split_all
from gsr_cad.reconstruct.surface import surface_metrics

RESOLUTION = 120
OPENING_SHARE = 0.15
MIN_LEAD = 0.002  # share of the solid's voxels
BODY_SPLITS = 2
SEGMENTS = 3
INSET = 0.25


def body_and_leads(path: str) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """The body's voxel centres and each lead as (where it leaves the body, its farthest point from there)."""
    mesh = trimesh.load(path, force="mesh")
    pitch = float(mesh.extents.max()) / RESOLUTION
    grid = mesh.voxelized(pitch).fill()
    solid = grid.matrix
    ball = ndimage.generate_binary_structure(3, 1)
    opened = ndimage.binary_opening(solid, structure=ball,
                                    iterations=max(1, round(OPENING_SHARE * float(mesh.extents.min()) / pitch)))
    labels, count = ndimage.label(opened)
    body = labels == 1 + int(np.argmax(ndimage.sum(opened, labels, range(1, count + 1))))
    labels, count = ndimage.label(solid & ~ndimage.binary_dilation(body, ball, iterations=1))
    near = ndimage.binary_dilation(body, ball, iterations=2)
    leads = []
    for k in range(1, count + 1):
        piece = labels == k
        root = np.argwhere(piece & near)
        if piece.sum() < MIN_LEAD * solid.sum() or not len(root):
            continue
        start = grid.indices_to_points(root).mean(axis=0)
        cells = grid.indices_to_points(np.argwhere(piece))
        leads.append((start, cells[int(np.argmax(np.linalg.norm(cells - start, axis=1)))]))
    return grid.indices_to_points(np.argwhere(body)), leads


def with_leads(cage: PolyMesh, leads: list[tuple[np.ndarray, np.ndarray]]) -> PolyMesh:
    """An inset and ``SEGMENTS`` extrusions per lead, each from its own face (a lead whose face is taken, or whose
    ops refuse, is left out)."""
    used: set[int] = set()
    for start, far in leads:
        d = far - start
        score = np.linalg.norm(cage.face_centroids - start, axis=1) - 0.5 * np.maximum(cage.face_normals @ d, 0.0)
        face = int(np.argmin(score))
        if face in used:
            continue
        corners = cage.vertices[list(cage.faces[face])]
        size = float(np.linalg.norm(corners - corners.mean(axis=0), axis=1).min())
        try:
            built = Inset(face, INSET * size).apply(cage)
            for _ in range(SEGMENTS):
                built = Extrude(face, float(np.linalg.norm(d)) / SEGMENTS).apply(built)
        except OpError:
            continue
        used.add(face)
        cage = built
    return cage


def _row(label: str, cage: PolyMesh, target: SurfaceTarget, config: SurfaceConfig) -> str:
    m = surface_metrics(cage, target, config)
    both = 0.5 * (m["data_to_fit_mean"] + m["fit_to_data_mean"])
    return f"| {label} | {cage.n_vertices} | {m['data_to_fit_mean']:.2e} / {m['fit_to_data_mean']:.2e} | {both:.2e} |"


def _baseline_row(name: str, target: SurfaceTarget, vertices: int, config: SurfaceConfig) -> None:
    b = baseline(target, vertices, config)
    print(_row(f"{name}: baseline", b.control, target, config) if b.control is not None
          else f"| {name}: baseline | - | no quad remesh near {vertices} V | - |", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="+")
    args = ap.parse_args(argv)
    config = SurfaceConfig()
    print("| part: cage | V | data->fit / fit->data mean | both |\n|---|---|---|---|")
    for path in args.parts:
        target = surface_target(path)
        body, leads = body_and_leads(path)
        cage = place_cube(body).mesh
        for _ in range(BODY_SPLITS):
            cage = split_all(cage, cage)[2]  # the split on the Catmull-Clark step's vertices (the same limit)
        name = path.rsplit("/", 1)[-1]
        print(_row(f"{name}: body box split", fitted(target, config, cage), target, config), flush=True)
        raw = with_leads(cage, leads)
        built = fitted(target, config, raw)
        print(_row(f"{name}: + {len(leads)} leads", built, target, config), flush=True)
        _baseline_row(name, target, built.n_vertices, config)
        split = fitted(target, config, split_all(raw, built)[2])  # loops cut on the unfitted cage
        print(_row(f"{name}: + leads, split", split, target, config), flush=True)
        _baseline_row(name, target, split.n_vertices, config)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
