"""Surface distances: exact closest points against trimesh and brute force, the paper's mixed mean distance
against a literal transcription of its definition, and the symmetric point-to-surface measure."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from trimesh.triangles import closest_point as trimesh_closest_point

from gsr_cad.errors import InputError
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.geometry.surface_distance import (NearTriangles, TriangleSet, chord_sag, closest_on_triangles,
                                               cloud_distance,
                                               mixed_mean_distance, point_to_surface, sampling_radius,
                                               triangulate)

coords = st.floats(-10, 10, allow_nan=False, allow_infinity=False, width=64)
grid = st.integers(-40, 40).map(lambda i: i / 4)  # coarse values: many exactly degenerate triangles
fine = st.integers(-10_000, 10_000).map(lambda i: i / 1000)  # trimesh's own tolerances fail on specks


def brute_force(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Distance of every point to every triangle by trimesh (an independent implementation), minimum."""
    tri = vertices[triangles]
    out = np.empty(len(points))
    for i, p in enumerate(points):
        q = trimesh_closest_point(tri, np.repeat(p[None], len(tri), axis=0))
        out[i] = np.linalg.norm(q - p, axis=1).min()
    return out


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each ``p`` to the segment ``a b`` (a point when ``a == b``)."""
    ab = b - a
    len2 = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    return np.linalg.norm(p - a - t[:, None] * ab, axis=1)


def paper_mixed_mean(a: np.ndarray, t: np.ndarray, diagonal: float) -> float:
    """Section 4 of the paper, word for word, with explicit distance matrices."""
    d = np.linalg.norm(a[:, None] - t[None], axis=2)

    def one_way(dist: np.ndarray) -> float:
        terms = []
        for v in range(dist.shape[0]):
            t_near = int(np.argmin(dist[v]))            # closest vertex t on the other mesh
            back = int(np.argmin(dist[:, t_near]))      # from t, the closest vertex on this mesh
            terms.append(dist[v, t_near] if back == v else diagonal)
        return float(np.mean(terms))

    return max(one_way(d), one_way(d.T))


# --- point-triangle projection ------------------------------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, (40, 4, 3), elements=st.one_of(grid, fine)))
def test_closest_on_triangles_matches_trimesh(data):
    p, a, b, c = data[:, 0], data[:, 1], data[:, 2], data[:, 3]
    dist, point, bary = closest_on_triangles(p, a, b, c)
    # trimesh for proper triangles; the nearest of the three edges for (nearly) collinear ones
    sin2 = np.linalg.norm(np.cross(b - a, c - a), axis=1) ** 2
    proper = sin2 > 1e-6 * np.maximum(np.linalg.norm(b - a, axis=1) ** 2 * np.linalg.norm(c - a, axis=1) ** 2, 1e-300)
    want = np.minimum.reduce([segment_distance(p, a, b), segment_distance(p, b, c), segment_distance(p, a, c)])
    if proper.any():
        tm = trimesh_closest_point(np.stack([a, b, c], axis=1)[proper], p[proper])
        want[proper] = np.linalg.norm(tm - p[proper], axis=1)
    np.testing.assert_allclose(dist, want, atol=1e-7)
    # the point is the barycentric combination, inside the triangle
    np.testing.assert_allclose(point, bary[:, :1] * a + bary[:, 1:2] * b + bary[:, 2:] * c, atol=1e-9)
    assert np.all(bary >= -1e-12) and np.allclose(bary.sum(axis=1), 1.0)


def test_degenerate_triangles_are_segments_and_points():
    p = np.array([[0.5, 1.0, 0.0], [3.0, 0.0, 0.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0]])
    a = np.array([[0.0, 0, 0], [0, 0, 0], [1, 1, 0], [1, 0, 1]])
    b = np.array([[1.0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 0.75, 1]])
    c = np.array([[2.0, 0, 0], [2, 0, 0], [1, 1, 0], [1, 1.14352181, 1]])  # collinear x2, a point, collinear
    dist, _, _ = closest_on_triangles(p, a, b, c)
    np.testing.assert_allclose(dist, [1.0, 1.0, 1.0, 0.0], atol=1e-15)


# --- TriangleSet: exact nearest triangle ---------------------------------------------------------------------

def random_soup(rng: np.random.Generator, n_tri: int, spread: float) -> tuple[np.ndarray, np.ndarray]:
    centres = rng.uniform(-1, 1, (n_tri, 3))
    sizes = np.exp(rng.uniform(np.log(0.01), np.log(spread), n_tri))  # triangles of very different sizes
    verts = (centres[:, None] + sizes[:, None, None] * rng.normal(size=(n_tri, 3, 3))).reshape(-1, 3)
    return verts, np.arange(3 * n_tri).reshape(-1, 3)


@pytest.mark.parametrize("seed, spread", [(0, 0.05), (1, 0.5), (2, 2.0)])
def test_triangle_set_equals_brute_force(seed, spread):
    rng = np.random.default_rng(seed)
    verts, tris = random_soup(rng, 150, spread)
    points = rng.uniform(-2, 2, (300, 3))
    found = TriangleSet(verts, tris).closest(points)
    np.testing.assert_allclose(found.distance, brute_force(points, verts, tris), atol=1e-9)
    # the reported triangle and point agree with the distance
    own = trimesh_closest_point(verts[tris[found.triangle]], points)
    np.testing.assert_allclose(np.linalg.norm(own - points, axis=1), found.distance, atol=1e-9)
    np.testing.assert_allclose(found.point, own, atol=1e-9)


def test_triangle_set_on_a_limit_mesh_and_points_on_it():
    lim = limit_mesh(unit_cube(), 2)
    tris = triangulate(lim.corners, lim.offsets)
    ts = TriangleSet(lim.vertices, tris)
    assert np.abs(ts.closest(lim.vertices).distance).max() < 1e-12
    rng = np.random.default_rng(3)
    points = rng.normal(size=(200, 3)) * 0.4
    np.testing.assert_allclose(ts.closest(points).distance, brute_force(points, lim.vertices, tris), atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40))
def test_triangle_set_property(seed, n_tri):
    rng = np.random.default_rng(seed)
    verts, tris = random_soup(rng, n_tri, 1.0)
    points = rng.uniform(-2, 2, (20, 3))
    np.testing.assert_allclose(TriangleSet(verts, tris).closest(points).distance,
                               brute_force(points, verts, tris), atol=1e-9)


def test_triangle_set_with_slivers_stays_small_and_exact():
    rng = np.random.default_rng(7)
    verts, tris = random_soup(rng, 300, 0.05)
    # long slivers: 40 triangles hundreds of times longer than the others
    start = rng.uniform(-1, 1, (40, 3))
    sliver_v = np.concatenate([start, start + rng.normal(0, 5, (40, 3)), start + rng.normal(0, 1e-3, (40, 3))])
    sliver_t = np.arange(120).reshape(3, 40).T + len(verts)
    verts, tris = np.concatenate([verts, sliver_v]), np.concatenate([tris, sliver_t])
    ts = TriangleSet(verts, tris)
    assert ts._tree.n + ts._long._tree.n < 64 * len(tris)
    points = rng.uniform(-3, 3, (200, 3))
    np.testing.assert_allclose(ts.closest(points).distance, brute_force(points, verts, tris), atol=1e-9)


def test_triangle_set_rejects_bad_input():
    with pytest.raises(InputError):
        TriangleSet(np.zeros((3, 3)), np.zeros((0, 3), dtype=int))
    with pytest.raises(InputError):
        TriangleSet(np.zeros((3, 3)), np.array([[0, 1, 3]]))


def test_triangulate_fans_each_face_from_its_first_corner():
    tri = triangulate(np.array([0, 1, 2, 3, 4, 5, 6, 7, 8]), np.array([0, 4, 9]))
    np.testing.assert_array_equal(tri, [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [4, 7, 8]])


# --- the paper's mixed mean distance -------------------------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 25), st.just(3)), elements=coords),
       arrays(np.float64, st.tuples(st.integers(1, 25), st.just(3)), elements=coords))
def test_mixed_mean_matches_the_papers_definition(a, t):
    # ties make "the closest vertex" ambiguous in the literal version; keep the sets tie-free
    for s in (a, t):
        if len(np.unique(s.round(6), axis=0)) < len(s):
            return
    d = np.linalg.norm(a[:, None] - t[None], axis=2)
    if any(np.any(np.diff(np.sort(x, axis=1)[:, :2], axis=1) < 1e-9) for x in (d, d.T)):
        return
    diag = 7.0
    assert mixed_mean_distance(a, t, diag) == pytest.approx(paper_mixed_mean(a, t, diag), abs=1e-12)


def test_mixed_mean_on_identical_sets_is_zero_and_an_extra_point_costs_a_diagonal():
    rng = np.random.default_rng(5)
    a = rng.normal(size=(50, 3))
    assert mixed_mean_distance(a, a[::-1], 3.0) == 0.0
    # one extra target vertex right next to a[0]: a[0] still pairs with its twin, the extra one does not
    t = np.vstack([a, a[:1] + 1e-3])
    assert mixed_mean_distance(a, t, 3.0) == pytest.approx(3.0 / 51)


def test_mixed_mean_ignores_vertex_order_under_ties():
    a = np.array([[0.0, 0, 0], [0, 0, 0], [1, 0, 0]])  # a duplicated vertex: both are "the closest"
    t = np.array([[0.0, 0, 0], [1, 0, 0]])
    assert mixed_mean_distance(a, t, 2.0) == mixed_mean_distance(a[[1, 0, 2]], t, 2.0) == 0.0


# --- symmetric point-to-surface ------------------------------------------------------------------------------

def test_point_to_surface_on_a_plane_is_the_height():
    square = np.array([[-5.0, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]])
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    rng = np.random.default_rng(0)
    h = rng.uniform(-1, 1, 100)
    points = np.column_stack([rng.uniform(-4, 4, (100, 2)), h])
    d = point_to_surface(square, tris, points, target_surface=TriangleSet(square, tris))
    np.testing.assert_allclose(d.to_surface, np.abs(h), atol=1e-12)
    np.testing.assert_allclose(d.to_target, 0.0)
    np.testing.assert_allclose(d.closest.point[:, 2], 0.0, atol=1e-12)


def test_point_to_surface_is_zero_for_the_same_surface_whatever_the_sampling():
    lim = limit_mesh(unit_cube(), 2)
    tris = triangulate(lim.corners, lim.offsets)
    rng = np.random.default_rng(1)
    # a cloud on the surface, denser than and unlike its vertices
    pick = rng.integers(len(tris), size=800)
    w = rng.dirichlet(np.ones(3), size=800)
    cloud = np.einsum("nk,nkj->nj", w, lim.vertices[tris[pick]])
    d = point_to_surface(lim.vertices, tris, cloud)
    assert d.to_surface.max() < 1e-12 and d.to_target.max() == 0.0
    # the paper's measure keeps a floor for the same pair (its density is unlike the mesh's)
    assert mixed_mean_distance(lim.vertices, cloud, lim.diagonal) > 0.1 * lim.diagonal
    # a shrunk copy is found at the right distance from a mesh target
    small = lim.vertices * 0.9
    back = point_to_surface(small, tris, lim.vertices, target_surface=TriangleSet(lim.vertices, tris))
    assert back.to_surface.min() > 0 and back.symmetric > 0
    np.testing.assert_allclose(back.to_surface, brute_force(lim.vertices, small, tris), atol=1e-12)
    np.testing.assert_allclose(back.to_target, brute_force(small, lim.vertices, tris), atol=1e-12)


def test_cloud_distance_and_sampling_radius():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [3, 0, 0], [6, 0, 0]])
    np.testing.assert_allclose(sampling_radius(pts, k=1), [1, 1, 2, 3])
    np.testing.assert_allclose(sampling_radius(pts, k=2), [3, 2, 3, 5])
    d, idx = cloud_distance(np.array([[0.0, 0.5, 0], [6, 10, 0]]), pts, np.array([1.0, 1, 1, 2]))
    np.testing.assert_allclose(d, [0.0, 8.0])
    np.testing.assert_array_equal(idx, [0, 3])


@pytest.mark.parametrize("count", [300, 5000])
def test_near_triangles_agree_with_the_exact_closest_points(count):
    mesh = limit_mesh(unit_cube(), 4)
    tris = np.array([t for f in mesh.faces for t in ((f[0], f[1], f[2]), (f[0], f[2], f[3]))])
    v = mesh.vertices
    area = 0.5 * np.linalg.norm(np.cross(v[tris[:, 1]] - v[tris[:, 0]], v[tris[:, 2]] - v[tris[:, 0]]), axis=1).sum()
    rng = np.random.default_rng(5)
    far = v.mean(axis=0) + rng.normal(size=(3000, 3)) * 0.5 * mesh.diagonal
    near = v[rng.integers(len(v), size=3000)] + rng.normal(size=(3000, 3)) * 1e-3 * mesh.diagonal
    x = np.concatenate([far, near])
    exact = TriangleSet(v, tris).closest(x).distance
    d, point = NearTriangles(v, tris, count).closest(x)
    assert np.all(d >= exact - 1e-12)  # a point of the mesh: never nearer than the nearest
    np.testing.assert_allclose(np.linalg.norm(point - x, axis=1), d, atol=1e-12)
    spacing = np.sqrt(area / (count + len(tris)))  # the samples' spacing
    assert np.abs(d - exact).max() < 0.25 * spacing  # a neighbour of the nearest triangle at worst
    assert np.mean(d > exact + 1e-9 * mesh.diagonal) < 0.05 and np.mean(d - exact) < 1e-3 * spacing


@pytest.mark.parametrize("subdivisions", [1, 2, 3, 4])
def test_chord_sag_bounds_how_far_the_sphere_lies_from_its_tessellation(subdivisions):
    """Points of the unit sphere are within (about) their nearest triangle's sag of an icosphere, at every
    density, and the sag is not much larger than that: a fit may leave exactly the tessellation's own error."""
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
    sag = chord_sag(mesh.vertices, mesh.faces)
    p = np.random.default_rng(subdivisions).normal(size=(5000, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    near = TriangleSet(mesh.vertices, mesh.faces).closest(p)
    ratio = near.distance / sag[near.triangle]
    assert ratio.max() <= 1.15 and ratio.mean() >= 0.5


def test_chord_sag_is_zero_on_flat_faces_and_sharp_edges():
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    assert not chord_sag(box.vertices, box.faces).any()
    cylinder = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=32)
    sag = chord_sag(cylinder.vertices, cylinder.faces)
    normals = cylinder.face_normals
    caps = np.abs(normals[:, 2]) > 0.99
    assert not sag[caps].any() and (sag[~caps] > 0).all()


@pytest.mark.parametrize("height", [2.0, 20.0])
def test_chord_sag_of_a_cylinder_is_its_strips_width_not_their_length(height):
    """A CAD export tessellates a cylinder into long strips: the surface lies within ``k w^2 / 8`` of them
    (``w`` the strip's width), however long they are; their enclosing circle would charge their length."""
    sections = 32
    cylinder = trimesh.creation.cylinder(radius=1.0, height=height, sections=sections)
    sag = chord_sag(cylinder.vertices, cylinder.faces)
    side = np.abs(cylinder.face_normals[:, 2]) < 0.01
    true = 1.0 - np.cos(np.pi / sections)  # the arc's distance from its chord
    assert np.allclose(sag[side], true, rtol=0.05)
    rng = np.random.default_rng(1)
    phi, z = rng.uniform(0, 2 * np.pi, 4000), rng.uniform(-0.45, 0.45, 4000) * height
    p = np.stack([np.cos(phi), np.sin(phi), z], axis=1)
    near = TriangleSet(cylinder.vertices, cylinder.faces).closest(p)
    assert (near.distance <= 1.05 * sag[near.triangle]).all()
