"""Foot points on a creased limit surface: a point inside a sharp convex edge has a local minimum of its
distance on each side of it, and the closest point search must find the nearer one (issue 13: a flat-capped
cylinder measured 5.7e-3 of the diagonal from its fit where the true distance was 5.5e-4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from gsr_cad.geometry.limit_surface import LimitSurface
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.geometry.subdivision import get_catmull_clark, limit_mesh
from gsr_cad.ops.mesh import CreaseRim, EdgeLoop
from test_limit_surface import _brute


def rimmed_box():
    """A cube with both caps' rims infinitely sharp and three edge loops (a coarse flat-capped cylinder)."""
    mesh = CreaseRim(5, 10.0).apply(CreaseRim(4, 10.0).apply(unit_cube()))
    for edge in (0, 1, 2):
        mesh = EdgeLoop(edge).apply(mesh)
    return mesh


def _inside_the_rim(mesh, count: int, seed: int) -> np.ndarray:
    """Points just inside the top cap's sharp rim: below the cap and inward of the wall by 0.5 to 5 %."""
    top = limit_mesh(mesh, 4).vertices
    top = top[np.isclose(top[:, 2], top[:, 2].max(), atol=1e-9)]
    rim = top[ConvexHull(top[:, :2]).vertices]
    rng = np.random.default_rng(seed)
    at = rim[rng.choice(len(rim), count)]
    inward = rng.uniform(0.005, 0.05, (count, 1)) * mesh.diagonal
    down = rng.uniform(0.005, 0.05, (count, 1)) * mesh.diagonal
    radial = at * [1.0, 1.0, 0.0]
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    return at - inward * radial - down * [0.0, 0.0, 1.0]


def _inside_the_rim_corners(mesh, count: int, seed: int) -> np.ndarray:
    """Points just inside the top cap's rim near the limit points of its vertices, where four patches meet
    (two of the cap, two of the wall)."""
    limit = get_catmull_clark(mesh, 1).limit_matrix[:mesh.n_vertices] @ mesh.vertices
    top = limit[np.isclose(mesh.vertices[:, 2], mesh.vertices[:, 2].max())]
    rim = top[np.linalg.norm(top[:, :2], axis=1) > 0.1]
    rng = np.random.default_rng(seed)
    at = rim[rng.choice(len(rim), count)]
    radial = at * [1.0, 1.0, 0.0]
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    tangent = np.cross([0.0, 0.0, 1.0], radial)
    scale = mesh.diagonal
    return (at - rng.uniform(0.001, 0.02, (count, 1)) * scale * radial
            - rng.uniform(0.001, 0.02, (count, 1)) * scale * [0.0, 0.0, 1.0]
            + rng.uniform(-0.02, 0.02, (count, 1)) * scale * tangent)


@pytest.mark.parametrize("near", [_inside_the_rim, _inside_the_rim_corners])
@pytest.mark.parametrize("seed", [0, 1])
def test_points_inside_a_sharp_rim_find_the_nearer_side(near, seed):
    mesh = rimmed_box()
    surface = LimitSurface.of(mesh)
    x = near(mesh, 120, seed)
    found = surface.closest(x)
    np.testing.assert_allclose(found.distance, _brute(surface, x), rtol=1e-7, atol=1e-12)


def test_the_search_samples_cover_their_patches():
    """Every point of a patch lies within its covering radius of a search sample of its own (the bound
    that prunes the candidate patches)."""
    surface = LimitSurface.of(rimmed_box())
    g = np.linspace(0.0, 1.0, 21)
    u, v = np.repeat(g, g.size), np.tile(g, g.size)
    for tree, owner, _, radius in surface._search():
        for patch in np.unique(owner)[::5]:
            mine = owner == patch
            points = surface.evaluate(np.full(u.size, patch), u, v)
            gap = np.linalg.norm(points[:, None] - tree.data[mine][None], axis=2).min(axis=1)
            assert gap.max() <= radius[mine][0] * (1 + 1e-12)
