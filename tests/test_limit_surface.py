"""The exact limit surface: patches reproduce limit points at every density, foot points equal brute force
on curved surfaces, rows are the linear map of the control vertices, area samples integrate the area,
area sampling of mesh targets."""

from __future__ import annotations

import numpy as np
import pytest

from gsr_cad.geometry.limit_surface import LimitSurface, _bases, _grid_params, bspline_basis, build_layout, get_layout
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.geometry.subdivision import get_catmull_clark, limit_mesh
from gsr_cad.geometry.surface_distance import area_samples, closest_on_triangles
from gsr_cad.ops.mesh import Extrude, Inset
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES


def curved_meshes():
    """A cube, an inset-extruded cube with moved vertices (valences 3, 4 and 5) and a prism (n-gons)."""
    cube = unit_cube()
    rng = np.random.default_rng(3)
    bumpy = Extrude(0, 0.6).apply(Inset(1, 0.3).apply(cube))
    bumpy = bumpy.with_vertices(bumpy.vertices + rng.normal(0, 0.03, bumpy.vertices.shape))
    s = SURFACE_SAMPLES["flattened_extended"]()
    return [cube, bumpy, s.truth_control]


@pytest.mark.parametrize("mesh_index", [0, 1, 2])
@pytest.mark.parametrize("level", [1, 2, 3, 4])
def test_limit_points_of_every_density_lie_on_the_surface(mesh_index, level):
    mesh = curved_meshes()[mesh_index]
    surface = LimitSurface.of(mesh)
    points = get_catmull_clark(mesh, level).limit_matrix @ mesh.vertices
    assert surface.closest(points).distance.max() < 1e-12 * mesh.diagonal


def _brute(surface: LimitSurface, x: np.ndarray) -> np.ndarray:
    """Distance by brute force: Gauss-Newton on every patch from its nearest point of a 17 x 17 grid, and
    every pending triangle."""
    n_p = surface.layout.n_patches
    u, v = _grid_params(17)
    grid = surface.evaluate(np.repeat(np.arange(n_p), u.size), np.tile(u, n_p), np.tile(v, n_p)).reshape(n_p, -1, 3)
    best = np.full(len(x), np.inf)
    for i, p in enumerate(x):
        near = np.linalg.norm(grid - p, axis=2).argmin(axis=1)
        fu, fv = surface.foot_points(np.arange(n_p), u[near], v[near], np.repeat(p[None], n_p, axis=0))
        best[i] = np.linalg.norm(surface.evaluate(np.arange(n_p), fu, fv) - p, axis=1).min()
        t = surface.layout.triangles
        if len(t):
            c = surface.corner_points
            d = closest_on_triangles(np.repeat(p[None], len(t), 0), c[t[:, 0]], c[t[:, 1]], c[t[:, 2]])[0]
            best[i] = min(best[i], d.min())
    return best


@pytest.mark.parametrize("mesh_index", [0, 1, 2])
@pytest.mark.parametrize("spread", [0.003, 0.05])
def test_foot_points_equal_brute_force(mesh_index, spread):
    mesh = curved_meshes()[mesh_index]
    surface = LimitSurface.of(mesh, depth=3)
    rng = np.random.default_rng(mesh_index)
    on = limit_mesh(mesh, 4).vertices[rng.choice(limit_mesh(mesh, 4).n_vertices, 60, replace=False)]
    x = on + rng.normal(0, spread * mesh.diagonal, on.shape)
    found = surface.closest(x)
    np.testing.assert_allclose(found.distance, _brute(surface, x), rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(found.point - x, axis=1), found.distance, atol=1e-12)


def test_foot_points_beyond_a_patch_border_converge_along_it():
    """A point whose foot on a patch lies on the patch's border: the parameter at its bound stays there and the
    other converges along the border (a joint Newton step, clipped, zigzags and was still moving after the
    iterations ran out). Started again from what it found, the Newton step does not move it."""
    mesh = curved_meshes()[1]
    surface = LimitSurface.of(mesh, depth=3)
    rng = np.random.default_rng(11)
    count = 400
    patch = rng.integers(0, surface.layout.n_patches, count)
    u, v = rng.uniform(0.0, 1.0, count), rng.uniform(0.0, 1.0, count)
    p, su, sv = surface.evaluate(patch, u, v, derivatives=True)
    n = np.cross(su, sv)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    # pushed out across a border of the patch (tangentially) and off the surface (along the normal)
    side = rng.integers(0, 4, count)
    push = np.where((side < 2)[:, None], su, sv) * np.where(side % 2 == 0, -1.0, 1.0)[:, None]
    x = p + rng.uniform(0.2, 0.6, (count, 1)) * push + rng.uniform(-0.05, 0.05, (count, 1)) * n
    fu, fv = surface.foot_points(patch, rng.uniform(0.3, 0.7, count), rng.uniform(0.3, 0.7, count), x)
    border = (fu <= 0) | (fu >= 1) | (fv <= 0) | (fv >= 1)
    assert border.sum() > count // 4
    again_u, again_v = surface.foot_points(patch, fu, fv, x)
    moved = np.maximum(np.abs(again_u - fu), np.abs(again_v - fv))
    assert np.quantile(moved[border], 0.99) < 1e-9
    # and the foot is the nearest point of that border: no point along it is nearer
    t = np.linspace(0.0, 1.0, 2001)
    for i in np.flatnonzero(border)[:40]:
        along_u = fv[i] in (0.0, 1.0)
        uu = t if along_u else np.full_like(t, fu[i])
        vv = np.full_like(t, fv[i]) if along_u else t
        grid = surface.evaluate(np.full(t.size, patch[i]), uu, vv)
        found = np.linalg.norm(surface.evaluate(patch[i:i + 1], fu[i:i + 1], fv[i:i + 1])[0] - x[i])
        assert found <= np.linalg.norm(grid - x[i], axis=1).min() + 1e-12


def test_offsets_along_the_normal_are_the_distance():
    mesh = curved_meshes()[1]
    surface = LimitSurface.of(mesh)
    rng = np.random.default_rng(5)
    patch = rng.integers(0, surface.layout.n_patches, 300)
    u, v = rng.uniform(0.05, 0.95, 300), rng.uniform(0.05, 0.95, 300)
    p, su, sv = surface.evaluate(patch, u, v, derivatives=True)
    n = np.cross(su, sv)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    offset = rng.uniform(-1e-3, 1e-3, 300) * mesh.diagonal
    np.testing.assert_allclose(surface.closest(p + offset[:, None] * n).distance, np.abs(offset), rtol=1e-6,
                               atol=1e-12)


def test_rows_are_the_linear_map_of_the_control_vertices():
    mesh = curved_meshes()[1]
    surface = LimitSurface.of(mesh)
    hits = surface.closest(np.random.default_rng(0).normal(0, 0.5, (200, 3)))
    A = surface.rows(hits)
    np.testing.assert_allclose(A @ mesh.vertices, hits.point, atol=1e-12)
    moved = mesh.vertices + np.random.default_rng(1).normal(0, 0.05, mesh.vertices.shape)
    other = LimitSurface(surface.layout, moved)
    on = hits.patch >= 0
    np.testing.assert_allclose((A @ moved)[on], other.evaluate(hits.patch[on], hits.u[on], hits.v[on]), atol=1e-12)


def test_area_samples_integrate_the_area_and_depth_shrinks_the_pending_part():
    mesh = curved_meshes()[1]
    fine = limit_mesh(mesh, 6)
    tri = get_catmull_clark(mesh, 6).triangles
    v = fine.vertices
    area = 0.5 * np.linalg.norm(np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]]), axis=1).sum()
    pending = []
    for depth in (1, 3, 5):
        surface = LimitSurface(build_layout(mesh, "all", depth), mesh.vertices)
        hits, weight = surface.samples()
        assert weight.sum() == pytest.approx(area, rel=1e-2 if depth == 1 else 1e-3)
        pending.append(weight[hits.patch < 0].sum())
    assert pending[0] > 10 * pending[1] > 100 * pending[2]
    assert get_layout(mesh) is get_layout(mesh.with_vertices(mesh.vertices * 2))


def test_the_bases_of_every_order_at_once_are_the_basis_and_its_derivatives():
    """:func:`_bases` equals :func:`bspline_basis` of each order bit for bit, which is the cubic B-spline basis
    (partition of unity; a central difference gives the next order)."""
    t = np.random.default_rng(5).random(200)
    together = _bases(t)
    for k in range(3):
        assert np.array_equal(together[:, k], bspline_basis(t, k))
    np.testing.assert_allclose(together[:, 0].sum(axis=1), 1.0, atol=1e-15)
    h = 1e-6
    for k in (0, 1):
        np.testing.assert_allclose((bspline_basis(t + h, k) - bspline_basis(t - h, k)) / (2 * h), together[:, k + 1],
                                   atol=1e-6)


def test_area_samples_of_a_layout_built_once_follow_every_placement():
    """The area samples' maps are built once per connectivity; a second placement's samples are its own
    surface's points, unit normals and area elements (evaluated here from the patches' poles), and their rows
    map its control vertices to those points, bit for bit as a surface with a cold cache gives them."""
    mesh = curved_meshes()[1]
    layout = build_layout(mesh)
    moved = mesh.vertices + np.random.default_rng(2).normal(0, 0.05, mesh.vertices.shape)
    LimitSurface(layout, mesh.vertices).samples()  # fills the layout's maps
    surface = LimitSurface(layout, moved)
    hits, area = surface.samples()
    on = hits.patch >= 0
    p, du, dv = surface.evaluate(hits.patch[on], hits.u[on], hits.v[on], derivatives=True)
    np.testing.assert_allclose(hits.point[on], p, atol=1e-12)
    cross = np.cross(du, dv)
    np.testing.assert_allclose(hits.normal[on], cross / np.linalg.norm(cross, axis=1)[:, None], atol=1e-12)
    w = area[on] / np.linalg.norm(cross, axis=1)
    assert np.all(w > 0) and w.sum() == pytest.approx(float(np.unique(hits.patch[on]).size), rel=1e-12)
    t = layout.triangles[hits.triangle[~on]]
    corners = surface.corner_points[t]
    np.testing.assert_allclose(hits.point[~on], corners.mean(axis=1), atol=1e-12)
    np.testing.assert_allclose(surface.rows(hits) @ moved, hits.point, atol=1e-12)
    cold_hits, cold_area = LimitSurface(build_layout(mesh), moved).samples()
    assert np.array_equal(cold_hits.point, hits.point) and np.array_equal(cold_area, area)


def test_area_samples_of_a_mesh_weight_by_area_not_by_vertex():
    # a square made of one big triangle and many small ones on the other half: samples split by area
    fan = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]
    v = np.array(fan + [(0.5 + 0.5 * i / 20, 0.0, 0.0) for i in range(1, 20)])
    tris = [[0, 2, 3]]
    chain = [0] + list(range(4, 23)) + [1]
    tris += [[chain[i], chain[i + 1], 2] for i in range(len(chain) - 1)]
    pts = area_samples(v, np.array(tris), 20000, seed=1)
    assert v[:, 1].mean() < 0.1  # the vertices crowd the bottom edge
    np.testing.assert_allclose(pts[:, :2].mean(axis=0), [0.5, 0.5], atol=0.01)  # the area's centroid
    # a long sliver far larger than the rest is sampled inside, not only at its corners
    strip = np.array([[0, 0, 0], [10, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0], [0.1, 0.2, 0]], dtype=float)
    inside = area_samples(strip, np.array([[0, 1, 2], [2, 3, 4], [2, 0, 3], [3, 0, 4]]), 2000, seed=0)
    assert np.mean((inside[:, 0] > 0.2) & (inside[:, 0] < 9.9)) > 0.5
    assert np.array_equal(pts, area_samples(v, np.array(tris), 20000, seed=1))


def test_the_flat_faces_of_a_part_are_sampled_inside_and_a_smooth_tessellation_at_its_vertices():
    """A box's 12 triangles are its faces (sampled inside, so a fit sees the middle of each face); a sphere's
    and a cylinder wall's chords are not the surface (their vertices are), the cylinder's flat caps are."""
    import trimesh

    from gsr_cad.geometry.surface_distance import facet_triangles

    box = trimesh.creation.box()
    assert facet_triangles(box.vertices, box.faces).all()
    pts = area_samples(box.vertices, box.faces, 3000, seed=2)
    assert np.mean(np.abs(pts).max(axis=1) > 0.5 - 1e-12) == 1.0  # on the faces
    assert np.mean((np.abs(pts) < 0.45).sum(axis=1) == 2) > 0.6  # mostly inside them, not at the corners
    sphere = trimesh.creation.icosphere(2)
    assert not facet_triangles(sphere.vertices, sphere.faces).any()
    on = area_samples(sphere.vertices, sphere.faces, 2000, seed=2)
    np.testing.assert_allclose(np.linalg.norm(on, axis=1), 1.0, atol=1e-12)  # vertices of the unit sphere
    cylinder = trimesh.creation.cylinder(1.0, 2.0, sections=64)
    facets = facet_triangles(cylinder.vertices, cylinder.faces)
    normals = cylinder.face_normals
    np.testing.assert_array_equal(facets, np.abs(normals[:, 2]) > 0.99)
