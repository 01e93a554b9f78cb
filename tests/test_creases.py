"""Edge sharpness (creases) in PolyMesh and the Catmull-Clark kernel: OpenSubdiv (lagrange, which takes
sharpness / 10 per edge) as oracle for refined points and, where its limit is exact, limit points; exact
limits across levels; the crease, corner and dart rules by hand; cache keys."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from test_subdivision import MESHES, OPEN, match_meshes

from gsr_cad.errors import ConfigError, InputError, TopologyError
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.geometry.subdivision import CatmullClark, get_catmull_clark, limit_mesh

OSD_BOUNDARY = {"all": "EdgeOnly", "corners": "EdgeAndCorner"}
SHARPNESS = (0.0, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 10.0)


def opensubdiv_creased(mesh: PolyMesh, levels: int, limit: bool, boundary: str) -> PolyMesh:
    """OpenSubdiv's result through lagrange with ``mesh``'s creases as its edge sharpness attribute."""
    lagrange = pytest.importorskip("lagrange")
    from lagrange.subdivision import SchemeType, VertexBoundaryInterpolation, subdivide_mesh

    m = lagrange.SurfaceMesh()
    m.add_vertices(np.array(mesh.vertices))
    for f in mesh.faces:
        m.add_polygon(np.array(f, dtype=np.uint32))
    m.initialize_edges()
    creases = mesh.creases
    values = np.array([creases.get(tuple(sorted(int(x) for x in m.get_edge_vertices(e))), 0.0) / 10.0
                       for e in range(m.num_edges)])
    attr = m.create_attribute("sharpness", element=lagrange.AttributeElement.Edge,
                              usage=lagrange.AttributeUsage.Scalar, initial_values=values)
    out = subdivide_mesh(m, num_levels=levels, scheme=SchemeType.CatmullClark, use_limit_surface=limit,
                         vertex_boundary_interpolation=getattr(VertexBoundaryInterpolation, OSD_BOUNDARY[boundary]),
                         edge_sharpness_attr=attr)
    return PolyMesh.from_faces(np.array(out.vertices), [out.get_facet_vertices(f) for f in range(out.num_facets)])


def random_creases(mesh: PolyMesh, rng: np.random.Generator) -> PolyMesh:
    """Any sharpness on any edge (darts, corners, semi-sharp transitions)."""
    s = rng.choice(SHARPNESS, size=mesh.topology.n_edges)
    return mesh.with_creases(dict(zip(map(tuple, mesh.topology.edges.tolist()), s)))


def rim_creases(mesh: PolyMesh, rng: np.random.Generator, most: float) -> PolyMesh:
    """Whole face rims creased (each edge the largest sharpness of its creased faces, at most ``most`` or
    infinite): no infinitely sharp dart, where OpenSubdiv's smooth limit stencil would be off the surface."""
    s = np.zeros(mesh.topology.n_edges)
    for f in np.flatnonzero(rng.random(mesh.n_faces) < 0.4):
        value = rng.choice([0.5, 1.0, most, 10.0])
        he = np.arange(mesh.offsets[f], mesh.offsets[f + 1])
        s[mesh.topology.he_edge[he]] = np.maximum(s[mesh.topology.he_edge[he]], value)
    return mesh.with_creases(dict(zip(map(tuple, mesh.topology.edges.tolist()), s)))


CASES = [(name, boundary) for name in MESHES for boundary in (("all", "corners") if name in OPEN else ("all",))]


@pytest.mark.parametrize("name,boundary", CASES)
def test_refinement_matches_opensubdiv(name, boundary):
    rng = np.random.default_rng(7)
    for _ in range(3):
        mesh = random_creases(MESHES[name], rng)
        for levels in (1, 2, 3):
            ours = get_catmull_clark(mesh, levels, boundary).refine(mesh.vertices)
            # OpenSubdiv computes the fractional weights of semi-sharp vertices in single precision
            assert match_meshes(ours, opensubdiv_creased(mesh, levels, False, boundary), mesh.diagonal) < 1e-8


@pytest.mark.parametrize("name,boundary", CASES)
def test_limit_matches_opensubdiv_where_its_limit_is_exact(name, boundary):
    """OpenSubdiv's limit takes the rules of the last level: exact once semi-sharp creases have decayed
    (sharpness <= levels) and where no infinitely sharp dart is."""
    rng = np.random.default_rng(11)
    for levels in (1, 2, 3):
        mesh = rim_creases(MESHES[name], rng, float(levels))
        ours = get_catmull_clark(mesh, levels, boundary).limit(mesh.vertices)
        assert match_meshes(ours, opensubdiv_creased(mesh, levels, True, boundary), mesh.diagonal) < 1e-8


@pytest.mark.parametrize("name,boundary", CASES)
def test_limit_is_the_same_surface_at_every_level(name, boundary):
    """Semi-sharp creases refined until they decay and the exact dart stencil: a level-k limit point is the
    limit of the vertex point it becomes (vertex points come first), so levels k and k + 2 agree."""
    rng = np.random.default_rng(3)
    for _ in range(3):
        mesh = random_creases(MESHES[name], rng)
        for levels in (0, 1, 2):
            ours = limit_mesh(mesh, levels, boundary).vertices
            fine = limit_mesh(mesh, levels + 2, boundary).vertices
            np.testing.assert_allclose(fine[: len(ours)], ours, atol=1e-12 * mesh.diagonal)


def _cube_with_sharp_top(sharpness: float) -> PolyMesh:
    cube = unit_cube()
    return cube.with_creases({(4, 5): sharpness, (5, 7): sharpness, (7, 6): sharpness, (6, 4): sharpness})


def test_crease_rules_by_hand():
    """Infinitely sharp rim of the cube's top face: rim vertices follow ``(u0 + 6 v + u1) / 8``, rim edge
    points are midpoints, and in the limit the rim is the cubic B-spline of the square (``(u0 + 4 v + u1) / 6``)."""
    mesh = _cube_with_sharp_top(10.0)
    cc = CatmullClark(mesh, 1)
    refined = cc.refine(mesh.vertices).vertices
    v = mesh.vertices
    np.testing.assert_allclose(refined[4], (v[5] + 6 * v[4] + v[6]) / 8)
    e = mesh.topology.edges.tolist()
    k = e.index([5, 7]) if [5, 7] in e else e.index([7, 5])
    np.testing.assert_allclose(refined[8 + k], (v[5] + v[7]) / 2)
    limit = limit_mesh(mesh, 0).vertices
    np.testing.assert_allclose(limit[4], (v[5] + 4 * v[4] + v[6]) / 6)
    assert np.allclose(limit[[4, 5, 6, 7], 2], 0.5)  # the rim stays in the plane of the top face


def test_corner_and_dart_rules():
    cube = unit_cube()
    corner = cube.with_creases({(0, 1): 10, (0, 2): 10, (0, 4): 10})  # three sharp edges: vertex 0 stays
    for levels in (0, 1, 3):
        np.testing.assert_allclose(limit_mesh(corner, levels).vertices[0], cube.vertices[0], atol=1e-15)
    assert np.allclose(CatmullClark(corner, 2).refine(cube.vertices).vertices[0], cube.vertices[0])
    dart = cube.with_creases({(0, 1): 10})  # one sharp edge: smooth vertex rule, moved
    smooth = CatmullClark(cube, 1).refine(cube.vertices).vertices
    np.testing.assert_allclose(CatmullClark(dart, 1).refine(cube.vertices).vertices[0], smooth[0])


def test_semi_sharp_blends_between_smooth_and_sharp():
    cube = unit_cube()
    smooth = limit_mesh(cube, 2).vertices
    sharp = limit_mesh(_cube_with_sharp_top(10.0), 2).vertices
    prev = -1.0
    for s in (0.25, 0.5, 1.0, 2.0, 3.0):
        z = limit_mesh(_cube_with_sharp_top(s), 2).vertices[4, 2]
        assert smooth[4, 2] < z < sharp[4, 2] and z > prev
        prev = z
    # sharpness 0.5 is halfway at the first step: edge point between smooth and midpoint
    half = CatmullClark(_cube_with_sharp_top(0.5), 1).refine(cube.vertices).vertices
    soft = CatmullClark(cube, 1).refine(cube.vertices).vertices
    hard = CatmullClark(_cube_with_sharp_top(1.0), 1).refine(cube.vertices).vertices
    np.testing.assert_allclose(half[8:20], (soft[8:20] + hard[8:20]) / 2)


def test_sharpness_is_part_of_the_cache_key():
    cube = unit_cube()
    creased = _cube_with_sharp_top(2.0)
    assert cube.connectivity_key == creased.connectivity_key != creased.topology_key
    assert get_catmull_clark(cube, 2) is not get_catmull_clark(creased, 2)
    assert get_catmull_clark(creased, 2) is get_catmull_clark(creased.with_vertices(cube.vertices * 2), 2)
    assert creased.with_vertices(cube.vertices * 2).creases == creased.creases
    assert _cube_with_sharp_top(3.0).topology_key != creased.topology_key


def test_crease_storage():
    cube = unit_cube()
    mesh = cube.with_creases({(5, 4): 2.0, (0, 1): 25.0, (1, 3): 0.0})
    assert mesh.creases == {(0, 1): 10.0, (4, 5): 2.0}
    assert mesh.edge_sharpness.sum() == 12.0 and not mesh.edge_sharpness.flags.writeable
    assert cube.with_creases({}).topology_key == cube.topology_key
    assert PolyMesh.from_faces(cube.vertices, cube.faces, {(4, 5): 1.0}).creases == {(4, 5): 1.0}
    with pytest.raises(TopologyError):
        cube.with_creases({(0, 7): 1.0})
    for bad in ({(0, 1): -1.0}, {(0, 1): float("nan")}, {(0,): 1.0}, [(0, 1)]):
        with pytest.raises(InputError):
            cube.with_creases(bad)
    with pytest.raises(InputError):
        CatmullClark(cube.topology, 1, sharpness=np.ones(3))


def test_topology_input_takes_sharpness_per_edge():
    mesh = _cube_with_sharp_top(1.5)
    a = CatmullClark(mesh.topology, 2, sharpness=mesh.edge_sharpness).limit_matrix
    b = CatmullClark(mesh, 2).limit_matrix
    assert abs(a - b).max() < 1e-15


def test_limit_points_lie_on_the_refined_surface_far_down():
    """Limit points are where refinement converges (a semi-sharp crease with sharpness above the levels)."""
    mesh = _cube_with_sharp_top(2.5)
    ours = limit_mesh(mesh, 1).vertices
    far = CatmullClark(mesh, 7).refine(mesh.vertices).vertices
    d, _ = cKDTree(far).query(ours)
    assert d.max() < 1e-3 * mesh.diagonal


@pytest.mark.parametrize("name,boundary", CASES)
def test_limit_at_darts_matches_opensubdiv_with_its_isolation(name, boundary):
    """At infinitely sharp darts lagrange takes the smooth stencil at its last level: ``dart_isolation=levels``
    gives its limit everywhere (creases of sharpness 0, 0.5, 1 or infinite, all decayed by level 1)."""
    rng = np.random.default_rng(5)
    for levels in (1, 2, 3):
        mesh = MESHES[name]
        s = rng.choice((0.0, 0.0, 0.0, 0.5, 1.0, 10.0), size=mesh.topology.n_edges)
        mesh = mesh.with_creases(dict(zip(map(tuple, mesh.topology.edges.tolist()), s)))
        ours = CatmullClark(mesh, levels, boundary, dart_isolation=levels).limit(mesh.vertices)
        assert match_meshes(ours, opensubdiv_creased(mesh, levels, True, boundary), mesh.diagonal) < 1e-8


def test_dart_isolation_converges_to_the_exact_dart_limit():
    dart = unit_cube().with_creases({(0, 1): 10.0})
    exact = limit_mesh(dart, 1).vertices
    gaps = [np.abs(CatmullClark(dart, 1, dart_isolation=q).limit(dart.vertices).vertices - exact).max()
            for q in (1, 5, 10, 40)]
    assert gaps[0] > 1e-2 and gaps[1] < 1e-3 and 5e-6 < gaps[2] < 2e-5 and gaps[3] < 1e-12, gaps
    assert np.all(np.diff(gaps) < 0)
    smooth = unit_cube()  # nothing changes without darts
    np.testing.assert_array_equal(CatmullClark(smooth, 2, dart_isolation=3).limit_matrix.toarray(),
                                  CatmullClark(smooth, 2).limit_matrix.toarray())
    for bad in (-1, 1.5, True, "10"):
        with pytest.raises(ConfigError):
            CatmullClark(dart, 1, dart_isolation=bad)
