"""A closed triangle mesh's solid as voxels (numpy and scipy only): the pieces a designer's start is read from
(module :mod:`gsr_cad.reconstruct.leads` and :mod:`gsr_cad.reconstruct.blocks`)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

RESOLUTION = 120
"""Voxels along the mesh's longest extent."""


def surface_points(points: np.ndarray, faces: np.ndarray, spacing: float) -> np.ndarray:
    """Points on every triangle, no two neighbours farther apart than ``spacing``: each triangle's vertices
    subdivided ``n`` times along its edges (barycentric grid), ``n`` from its longest edge."""
    tri = points[faces]
    longest = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    splits = np.maximum(np.ceil(longest / spacing).astype(np.int64), 1)
    out = [points]
    for n in np.unique(splits):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        bary = np.stack([n - i[keep] - j[keep], i[keep], j[keep]], axis=1) / n
        out.append(np.einsum("pk,tkd->tpd", bary, tri[splits == n]).reshape(-1, 3))
    return np.concatenate(out)


def is_closed(faces: np.ndarray) -> bool:
    """Whether every edge of the triangles ``faces`` is shared by exactly two of them."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return bool(len(counts)) and bool(np.all(counts == 2))


def solid_voxels(points: np.ndarray, faces: np.ndarray | None,
                 resolution: int = RESOLUTION) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A mesh's solid as voxels, ``resolution`` along its longest extent: ``(filled matrix, the position of voxel
    (0, 0, 0)'s centre, pitch)``; None for a cloud or a mesh that is not closed. The surface's voxels are those of
    points on it half a pitch apart (which keeps them 6-connected), then filled: as trimesh's subdividing
    voxeliser does, at a fraction of its time (14.5 s -> well under one on an 11,884-triangle OpenSCAD part)."""
    if faces is None or not is_closed(np.asarray(faces)):
        return None
    pitch = float(np.ptp(points, axis=0).max()) / resolution
    if not pitch > 0:
        return None
    hit = np.round(surface_points(points, faces, 0.5 * pitch) / pitch).astype(np.int64)
    low = hit.min(axis=0) - 1
    hit -= low
    matrix = np.zeros(tuple(hit.max(axis=0) + 2), dtype=bool)
    matrix[hit[:, 0], hit[:, 1], hit[:, 2]] = True
    return ndimage.binary_fill_holes(matrix), low * pitch, pitch
