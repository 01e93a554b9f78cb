"""Limit patches and STEP solids of creased control meshes: exact B-spline patches beside infinitely sharp
creases (the phantom-row rule), no smooth patch where a crease acts, C0 seams along creases, valid solids.

Oracles: the kernel's creased limit points (CatmullClark.limit_matrix, proven against OpenSubdiv through
lagrange in test_creases), scipy's BSpline for evaluating patches, and for STEP OCP's reader,
BRepCheck_Analyzer, ShapeAnalysis_Surface projections of exact limit points and mass properties.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import statuses, torus
from test_patches import scipy_patch

from gsr_cad.geometry import subdivision
from gsr_cad.geometry.patches import crease_stencils, limit_grids, limit_patches
from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.reconstruct.templates import genus_template

N, M = 8, 6  # torus: N around z, M around the tube


def wavy_torus(seed: int = 0) -> PolyMesh:
    """An ``N`` x ``M`` quad torus (every vertex of valence 4), vertices jittered."""
    mesh = torus(N, M)
    rng = np.random.default_rng(seed)
    return mesh.with_vertices(mesh.vertices + 0.05 * rng.normal(size=mesh.vertices.shape))


def meridians(mesh: PolyMesh, rings=(0, 3), sharpness: float = 10.0) -> PolyMesh:
    """Whole meridian loops ``i`` creased: every crease vertex has two opposite sharp edges."""
    return mesh.with_creases({(i * M + j, i * M + (j + 1) % M): sharpness for i in rings for j in range(M)})


def rims(mesh: PolyMesh, sharpness: float = 10.0, cos_angle: float = 0.5) -> PolyMesh:
    """Every edge whose two faces meet at more than ``acos(cos_angle)`` creased."""
    n, ef = mesh.face_normals, mesh.topology.edge_faces
    sharp = np.flatnonzero((n[ef[:, 0]] * n[ef[:, 1]]).sum(axis=1) < cos_angle)
    return mesh.with_creases({tuple(map(int, mesh.topology.edges[e])): sharpness for e in sharp})


def prism(n: int = 8) -> PolyMesh:
    a = 2 * np.pi * np.arange(n) / n
    v = np.concatenate([np.c_[np.cos(a), np.sin(a), np.zeros(n)], np.c_[np.cos(a), np.sin(a), np.full(n, 1.3)]])
    faces = [tuple(range(n - 1, -1, -1)), tuple(range(n, 2 * n))] + [(i, (i + 1) % n, n + (i + 1) % n, n + i)
                                                                    for i in range(n)]
    return PolyMesh.from_faces(v * 30, faces)


def parametric_gap(mesh: PolyMesh, patches, level: int = 5) -> np.ndarray:
    """Per patch, the largest ``|patch(u, v) - limit(u, v)|`` on the level-``level`` grid (scipy evaluation)."""
    grids = limit_grids(mesh, level)
    t = np.linspace(0, 1, grids.shape[1])
    return np.array([np.abs(scipy_patch(p, t, t) - g).max() for p, g in zip(patches.patches, grids)])


def test_a_crease_next_to_regular_quads_is_not_ignored():
    """Creases on an all-valence-4 torus: the smooth rule would put every patch off the creased limit."""
    mesh = wavy_torus()
    rng = np.random.default_rng(3)
    edges = mesh.topology.edges[rng.choice(mesh.topology.n_edges, 14, replace=False)]
    creased = mesh.with_creases({tuple(map(int, e)): s for e, s in zip(edges, np.tile([10.0, 2.5], 7))})
    smooth = limit_patches(mesh)
    assert smooth.n_exact == len(smooth.patches)
    # the smooth patches are far from the creased limit: the test can tell
    assert parametric_gap(creased, smooth).max() > 1e-2 * smooth.diagonal
    ps = limit_patches(creased, 1e-3, max_level=5)
    assert 0 < ps.n_exact < len(ps.patches) and ps.within_tolerance
    exact = np.array([p.exact for p in ps.patches])
    assert parametric_gap(creased, ps)[exact].max() < 1e-12 * ps.diagonal


def test_infinite_creases_give_exact_patches_meeting_at_an_angle():
    mesh = meridians(wavy_torus())
    ps = limit_patches(mesh)
    assert ps.n_exact == len(ps.patches) == 4 * N * M
    assert parametric_gap(mesh, ps).max() < 1e-12 * ps.diagonal
    # patches on both sides of a crease edge: same boundary points (C0), different tangent planes
    cc = subdivision.get_catmull_clark(mesh, 1)
    t1 = cc.topology
    s1 = subdivision.refined_sharpness(mesh, t1)
    smooth = limit_patches(mesh.with_creases(None))
    t = np.linspace(0, 1, 9)
    angles, smooth_angles = [], []
    for h in np.flatnonzero(s1[t1.he_edge] > 0)[:12]:
        g = t1.he_twin[h]
        a, b = ps.patches[h // 4], ps.patches[g // 4]
        side_a, side_b = _side(a, h % 4, t), _side(b, g % 4, t)[::-1]
        np.testing.assert_allclose(side_a, side_b, atol=1e-12 * ps.diagonal)
        angles.append(_normal_angle(a, h % 4, b, g % 4))
        smooth_angles.append(_normal_angle(smooth.patches[h // 4], h % 4, smooth.patches[g // 4], g % 4))
    assert min(angles) > 2.0 and max(smooth_angles) < 0.01  # degrees: a crease, where smooth seams are G1


def _side(patch, k: int, t: np.ndarray) -> np.ndarray:
    """Points along side ``k`` of a patch, from corner ``k`` to corner ``k + 1``."""
    grid = scipy_patch(patch, t, t)
    return [grid[:, 0], grid[-1, :], grid[::-1, -1], grid[0, ::-1]][k]


def _normal_angle(a, ka: int, b, kb: int) -> float:
    """Angle (degrees) between the normals of ``a`` and ``b`` at the middle of their shared sides."""
    def normal(p, k):
        mid = {0: (0.5, 0.0), 1: (1.0, 0.5), 2: (0.5, 1.0), 3: (0.0, 0.5)}[k]
        e = 1e-6
        u, v = mid
        du = scipy_patch(p, np.array([min(u + e, 1), max(u - e, 0)]), np.array([v]))[:, 0]
        dv = scipy_patch(p, np.array([u]), np.array([min(v + e, 1), max(v - e, 0)]))[0]
        n = np.cross(du[0] - du[1], dv[0] - dv[1])
        return n / np.linalg.norm(n)

    return float(np.degrees(np.arccos(np.clip(normal(a, ka) @ normal(b, kb), -1, 1))))


@pytest.mark.parametrize("sharpness", [1.5, 3.0])
def test_semi_sharp_loops_are_fitted_exactly(sharpness):
    """A semi-sharp loop leaves a piecewise bicubic limit: fitted patches with enough spans reproduce it."""
    mesh = meridians(wavy_torus(), sharpness=sharpness)
    ps = limit_patches(mesh, 1e-6, max_level=5)
    assert ps.n_exact == 4 * N * M - 2 * 2 * 2 * M  # the quads touching the two loops at level 1
    assert ps.within_tolerance and parametric_gap(mesh, ps).max() < 1e-10 * ps.diagonal


def test_stencils_flag_phantom_sides_and_refuse_irregular_creases():
    mesh = meridians(wavy_torus())
    cc = subdivision.get_catmull_clark(mesh, 1)
    s1 = subdivision.refined_sharpness(mesh, cc.topology)
    quads, _, phantom = crease_stencils(cc.topology, np.arange(4 * N * M), s1)
    assert quads.size == 4 * N * M and phantom.sum() == 2 * 2 * 2 * M and phantom.sum(axis=1).max() == 1
    # one more creased edge across a loop makes its ends crease corners (three sharp edges): not regular
    extra = mesh.with_creases({**mesh.creases, (0, M): 10.0})
    cc = subdivision.get_catmull_clark(extra, 1)
    quads, _, _ = crease_stencils(cc.topology, np.arange(4 * N * M), subdivision.refined_sharpness(extra, cc.topology))
    assert quads.size < 4 * N * M


# --- STEP: the creased limit as a valid closed solid ---------------------------------------------------------

STEP_MESHES = {"torus, creased meridians": lambda: meridians(wavy_torus()),
               "prism, creased rims": lambda: rims(prism(8)),
               "genus 1, semi-sharp rims": lambda: rims(genus_template(1), 2.0)}


@pytest.mark.parametrize("name", list(STEP_MESHES))
def test_creased_step_is_a_closed_solid_on_the_creased_limit(tmp_path, name):
    pytest.importorskip("OCP")
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from test_export_surface_step import limit_volume, surface_result

    from gsr_cad.exporters.checks import read_step_shape
    from gsr_cad.exporters.step import StepExporter

    mesh = STEP_MESHES[name]()
    assert mesh.creases
    result = surface_result(mesh)
    step, sidecar = StepExporter().export(result, tmp_path, "creased")
    stated = json.loads(sidecar.read_text())
    assert stated["solid"] and stated["max_deviation"] <= stated["tolerance"]
    checks = StepExporter().validate(step, result)
    assert all(c.passed for c in checks), [c for c in checks if not c.passed]
    got = statuses(checks)
    assert got["one closed solid"] == got["BRepCheck_Analyzer valid"] == got["deviation from the limit surface"] \
        == "pass"
    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(read_step_shape(step), props)
    assert props.Mass() == pytest.approx(limit_volume(mesh), rel=2e-3)
    # the smooth limit encloses a clearly different volume: the solid follows the creases
    assert abs(limit_volume(mesh.with_creases(None)) - props.Mass()) > 1e-2 * props.Mass()


# --- the GA's limit surface (geometry.limit_surface) follows the creases too ------------------------------------

def _random_creases(mesh: PolyMesh, seed: int) -> PolyMesh:
    """Darts, crease corners, semi-sharp and infinite edges anywhere."""
    rng = np.random.default_rng(seed)
    edges = mesh.topology.edges[rng.choice(mesh.topology.n_edges, 10, replace=False)]
    return mesh.with_creases({tuple(map(int, e)): float(s) for e, s in zip(edges, [10, 1.5, 3, 0.5, 10, 10, 2, 2.5, 10, 1])})


LIMIT_MESHES = {**STEP_MESHES, "torus, semi-sharp meridians": lambda: meridians(wavy_torus(), sharpness=2.5),
                "genus 1, creased rims": lambda: rims(genus_template(1)),
                "genus 2, random creases": lambda: _random_creases(subdivision.refine(genus_template(2), 1), 5)}


@pytest.mark.parametrize("name", list(LIMIT_MESHES))
def test_the_limit_surface_of_the_search_is_the_creased_one(name):
    from gsr_cad.geometry.limit_surface import LimitSurface

    mesh = LIMIT_MESHES[name]()
    surface = LimitSurface.of(mesh)
    for level in (1, 3):
        points = subdivision.get_catmull_clark(mesh, level).limit_matrix @ mesh.vertices
        assert surface.closest(points).distance.max() < 1e-12 * mesh.diagonal
    # the limit points of a finer level fall between pending corners only near irregular crease vertices
    points = subdivision.get_catmull_clark(mesh, 4).limit_matrix @ mesh.vertices
    assert surface.closest(points).distance.max() < 1e-6 * mesh.diagonal
    smooth = LimitSurface.of(mesh.with_creases(None))
    assert smooth.closest(points).distance.max() > 1e-2 * mesh.diagonal
