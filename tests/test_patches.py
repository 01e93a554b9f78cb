"""Limit-surface B-spline patches: exact regular patches, fitted ones within tolerance, watertight seams.

Oracles: the limit positions of refined vertices (CatmullClark.limit_matrix, proven against lagrange /
OpenSubdiv and Blender in test_subdivision), scipy's BSpline for evaluating the patches, and counts of
regular quads derived by hand.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from gsr_cad.errors import ConfigError, InputError
from gsr_cad.geometry import subdivision
from gsr_cad.geometry.patches import graded, limit_grids, limit_patches
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube


def grid_mesh(nx: int, ny: int, seed: int = 0) -> PolyMesh:
    rng = np.random.default_rng(seed)
    xy = np.stack(np.meshgrid(np.arange(nx + 1), np.arange(ny + 1)), -1).reshape(-1, 2).astype(float)
    v = np.column_stack([xy, 0.3 * rng.normal(size=len(xy))])
    faces = [(j * (nx + 1) + i, j * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i + 1, (j + 1) * (nx + 1) + i)
             for j in range(ny) for i in range(nx)]
    return PolyMesh.from_faces(v, faces)


def ngon_solid() -> PolyMesh:
    """A pentagonal prism: two pentagons (n-gons), quads, valence-3 vertices."""
    a = 2 * np.pi * np.arange(5) / 5
    v = np.concatenate([np.column_stack([np.cos(a), np.sin(a), np.zeros(5)]),
                        np.column_stack([np.cos(a), np.sin(a), np.full(5, 1.3)])])
    faces = [tuple(range(4, -1, -1)), tuple(range(5, 10))]
    faces += [(i, (i + 1) % 5, 5 + (i + 1) % 5, 5 + i) for i in range(5)]
    return PolyMesh.from_faces(v, faces)


def scipy_patch(patch, u, v):
    """The patch evaluated with scipy alone (an independent tensor-product evaluation)."""
    su = BSpline(patch.knots_u, np.moveaxis(patch.poles, 0, 0), patch.degree_u)
    inner = su(u)  # (len(u), nv, 3)
    sv = BSpline(patch.knots_v, np.moveaxis(inner, 1, 0), patch.degree_v)
    return np.moveaxis(sv(v), 0, 1)


def test_regular_patches_are_exact_and_counted():
    mesh = subdivision.refine(unit_cube(), 2)  # 96 quads, 8 valence-3 vertices
    ps = limit_patches(mesh)
    # after one more step, each valence-3 vertex touches 3 quads; every other quad is regular
    assert ps.n_exact == 384 - 8 * 3 and len(ps.patches) == 384
    grids = limit_grids(mesh, 4)
    t = np.linspace(0, 1, grids.shape[1])
    exact = [i for i, p in enumerate(ps.patches) if p.exact]
    for i in exact[::37]:
        p = ps.patches[i]
        assert p.poles.shape == (4, 4, 3)
        np.testing.assert_allclose(scipy_patch(p, t, t), grids[i], atol=1e-13)
    assert max(ps.patch_deviation[exact]) < 1e-13


@pytest.mark.parametrize("mesh", [unit_cube(), ngon_solid(), grid_mesh(3, 2, seed=4)],
                         ids=["cube", "pentagonal prism", "open grid"])
@pytest.mark.parametrize("boundary", ["all", "corners"])
def test_fitted_patches_meet_the_tolerance_and_interpolate_corners(mesh, boundary):
    ps = limit_patches(mesh, 1e-4, boundary)
    assert ps.within_tolerance and ps.max_deviation <= 1e-4 * ps.diagonal
    assert 0 <= ps.mean_deviation <= ps.max_deviation
    assert ps.closed == mesh.topology.is_closed
    grids = limit_grids(mesh, 3, boundary)
    corners = np.stack([grids[:, 0, 0], grids[:, -1, 0], grids[:, -1, -1], grids[:, 0, -1]], 1)
    got = np.stack([scipy_patch(p, [0.0, 1.0], [0.0, 1.0]) for p in ps.patches])
    np.testing.assert_allclose(got[:, [0, 1, 1, 0], [0, 0, 1, 1]], corners, atol=1e-12)
    # the deviation figure is honest: the patches' own points are no closer to the limit than stated
    # at the parameters where the limit is exact (parametric gaps bound the distance from above)
    fine = limit_grids(mesh, ps.level + 1, boundary)
    t = np.linspace(0, 1, fine.shape[1])
    gaps = [np.linalg.norm(scipy_patch(p, t, t) - fine[i], axis=-1).max() for i, p in enumerate(ps.patches)]
    assert ps.max_deviation <= max(gaps) + 1e-12


def seams(mesh: PolyMesh, ps) -> float:
    """Largest gap between the shared edges of neighbouring patches (evaluated with scipy)."""
    t1 = subdivision.get_catmull_clark(mesh, 1).topology
    s = np.linspace(0, 1, 23)
    zero, one = np.zeros(1), np.ones(1)

    def side(h):
        p, k = ps.patches[h // 4], h % 4
        pts = [scipy_patch(p, s, zero)[:, 0], scipy_patch(p, one, s)[0], scipy_patch(p, s[::-1], one)[:, 0],
               scipy_patch(p, zero, s[::-1])[0]][k]
        return pts

    worst = 0.0
    for h in range(len(t1.he_twin)):
        tw = t1.he_twin[h]
        if tw > h:
            worst = max(worst, float(np.abs(side(h) - side(tw)[::-1]).max()))
    return worst


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 2**31 - 1), st.sampled_from(["cube", "prism", "grid"]), st.floats(1e-3, 1e3))
def test_neighbouring_patches_share_their_edge_curve(seed, kind, scale):
    rng = np.random.default_rng(seed)
    base = {"cube": unit_cube(), "prism": ngon_solid(), "grid": grid_mesh(2, 3, seed)}[kind]
    if kind == "cube":
        base = subdivision.refine(base, 1)
    mesh = base.with_vertices((base.vertices + 0.08 * rng.normal(size=base.vertices.shape)) * scale)
    ps = limit_patches(mesh, 1e-3)
    assert ps.within_tolerance
    assert seams(mesh, ps) <= 1e-12 * scale


def test_tighter_tolerance_needs_more_spans():
    coarse = limit_patches(unit_cube(), 1e-3)
    fine = limit_patches(unit_cube(), 2e-5, max_level=5)
    assert fine.spans > coarse.spans and fine.max_deviation < coarse.max_deviation
    assert fine.within_tolerance
    hopeless = limit_patches(unit_cube(), 1e-9, max_level=3)
    assert not hopeless.within_tolerance and hopeless.level == 3


def test_bad_input_raises_typed_errors():
    with pytest.raises(InputError, match="PolyMesh"):
        limit_patches(np.zeros((3, 3)))
    for bad in (0.0, -1e-4, float("nan")):
        with pytest.raises(ConfigError, match="tolerance"):
            limit_patches(unit_cube(), bad)
    with pytest.raises(ConfigError, match="max_level"):
        limit_patches(unit_cube(), max_level=9)
    with pytest.raises(ConfigError, match="boundary"):
        limit_patches(unit_cube(), boundary="sharp")
    with pytest.raises(InputError, match="non-finite"):
        limit_patches(unit_cube().with_vertices(np.full((8, 3), np.nan)))


def bipyramid(n: int = 8, height: float = 1.0) -> PolyMesh:
    """Two cones of ``n`` triangles on a regular ``n``-gon: the apexes are smooth vertices of valence ``n``."""
    a = 2 * np.pi * np.arange(n) / n
    v = np.r_[np.c_[np.cos(a), np.sin(a), np.zeros(n)], [[0, 0, height], [0, 0, -height]]]
    return PolyMesh.from_faces(v, [(i, (i + 1) % n, n) for i in range(n)] + [((i + 1) % n, i, n + 1) for i in range(n)])


def test_graded_fit_converges_fast_at_a_high_valence_vertex():
    """At a valence-8 apex the limit leaves the vertex like t**0.7: fitted at uniform parameters the patches
    stay 6e-4 (of the limit's diagonal) off at level 4 (shrinking by ~0.5 per level); graded, 1.3e-4."""
    mesh = bipyramid(8)
    ps = limit_patches(mesh, 2e-4, max_level=4)
    assert ps.within_tolerance and ps.level == 4, ps.max_deviation / ps.diagonal
    finer = limit_patches(mesh, 1e-9, max_level=5)
    assert finer.max_deviation < 0.5 * ps.max_deviation


def test_graded_sides_agree_from_both_quads():
    """Reversing a side swaps its end exponents and mirrors the parameters: both quads fit one curve."""
    t = np.linspace(0, 1, 17)
    g0, g1 = np.array([0.6, 1.0, 0.8]), np.array([0.9, 1.0, 0.55])
    forward, backward = graded(t, g0, g1), graded(t, g1, g0)
    assert np.allclose(forward, 1 - backward[:, ::-1], atol=1e-15)
    assert np.allclose(forward[1], t) and np.all(np.diff(forward, axis=1) > 0)
