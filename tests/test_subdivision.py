"""Catmull-Clark subdivision: pinned cube values, OpenSubdiv (lagrange) as oracle, scipy B-spline boundary
curves, invariants (hypothesis), the cache, errors, and ``gsr subdivide`` end to end."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import opensubdiv, pentaprism, torus
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from gsr_cad.errors import ConfigError, InputError, TopologyError
from gsr_cad.geometry import subdivision as sd
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.geometry.subdivision import CatmullClark, get_catmull_clark, limit_mesh, refine
from gsr_cad.geometry.surface_distance import triangulate
from gsr_cad.geometry.topology import Topology
from gsr_cad.geometry.validation import validate_mesh
from gsr_cad.reconstruct.meshio import load_mesh, save_obj

# --- hand-made meshes (also used by test_blender_subsurf.py) -----------------------------------------


def _cube_faces():
    return [list(f) for f in unit_cube().faces]


def _extruded() -> PolyMesh:
    """Unit cube with its +z face extruded by 1 (one side quad per edge)."""
    c = unit_cube()
    top = c.vertices[[4, 5, 7, 6]] + [0, 0, 1]
    v = np.vstack([c.vertices, top])  # 8..11 above 4, 5, 7, 6
    faces = _cube_faces()[:5] + [[4, 5, 9, 8], [5, 7, 10, 9], [7, 6, 11, 10], [6, 4, 8, 11], [8, 9, 10, 11]]
    return PolyMesh.from_faces(v, faces)


def _inset_extruded() -> PolyMesh:
    """Unit cube, +z face inset by 0.2, the inner face extruded by 0.6 and tilted: extraordinary vertices."""
    c = unit_cube()
    ring = c.vertices[[4, 5, 7, 6]] * [0.6, 0.6, 1]  # 8..11
    cap = ring + [[0.1, 0, 0.6], [0.1, 0, 0.8], [0, 0.1, 0.7], [0, 0, 0.6]]  # 12..15
    v = np.vstack([c.vertices, ring, cap])
    faces = _cube_faces()[:5] + [[4, 5, 9, 8], [5, 7, 10, 9], [7, 6, 11, 10], [6, 4, 8, 11]]
    faces += [[8, 9, 13, 12], [9, 10, 14, 13], [10, 11, 15, 14], [11, 8, 12, 15], [12, 13, 14, 15]]
    return PolyMesh.from_faces(v, faces)


def _grid(nx: int = 4, ny: int = 3) -> PolyMesh:
    v = [[x, y, 0.15 * x * y - 0.1 * x * x] for y in range(ny) for x in range(nx)]
    faces = [[y * nx + x, y * nx + x + 1, (y + 1) * nx + x + 1, (y + 1) * nx + x] for y in range(ny - 1)
             for x in range(nx - 1)]
    return PolyMesh.from_faces(v, faces)


def _fan6() -> PolyMesh:
    t = np.linspace(0, 2 * np.pi, 7)[:-1]
    v = np.r_[[[0.0, 0.0, 0.4]], np.c_[np.cos(t), np.sin(t), 0.1 * np.cos(2 * t)]]
    return PolyMesh.from_faces(v, [[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)])


def _pyramid() -> PolyMesh:
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.4, 1]]
    return PolyMesh.from_faces(v, [[3, 2, 1, 0], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])


def _mixed_open() -> PolyMesh:
    """A pentagon, a quad and a triangle in a strip: n-gons on the boundary, two corners."""
    v = [[0, 0, 0], [1, 0, 0.1], [1.3, 0.8, 0], [0.5, 1.3, 0.2], [-0.3, 0.8, 0], [2, 0, 0], [2.2, 0.9, 0.3],
         [3, 0.2, 0]]
    return PolyMesh.from_faces(v, [[0, 1, 2, 3, 4], [1, 5, 6, 2], [5, 7, 6]])


MESHES: dict[str, PolyMesh] = {
    "cube": unit_cube(),
    "open_cube": PolyMesh.from_faces(unit_cube().vertices, _cube_faces()[:5]),
    "pentaprism": pentaprism(0.7, 1.3),
    "pyramid": _pyramid(),
    "extruded": _extruded(),
    "inset_extruded": _inset_extruded(),
    "torus": torus(5, 4),
    "grid": _grid(),
    "fan6": _fan6(),
    "mixed_open": _mixed_open(),
    "single_quad": PolyMesh.from_faces([[0, 0, 0], [1, 0, 0], [1, 1, 0.3], [0, 1, 0]], [[0, 1, 2, 3]]),
}
OPEN = ("open_cube", "grid", "fan6", "mixed_open", "single_quad")


def test_hand_made_meshes_are_valid():
    for name, mesh in MESHES.items():
        validate_mesh(mesh, require_closed=name not in OPEN)


# --- pinned values (DESIGN.md) ------------------------------------------------------------------------


def test_cube_one_step_pinned():
    cube = unit_cube()
    out = refine(cube, 1)
    topo = cube.topology
    assert (out.n_vertices, out.n_faces) == (26, 24)
    np.testing.assert_allclose(out.vertices[:8], np.sign(cube.vertices) * 5 / 18, atol=1e-15)
    mid = cube.vertices[topo.edges].mean(axis=1)
    np.testing.assert_allclose(out.vertices[8:20], mid * 0.75, atol=1e-15)  # (0, +-3/8, +-3/8) per axis
    assert np.allclose(np.sort(np.abs(out.vertices[8:20]), axis=1), [0, 3 / 8, 3 / 8])
    np.testing.assert_allclose(out.vertices[20:], cube.face_centroids, atol=1e-15)
    assert np.allclose(np.abs(out.vertices[20:]).max(axis=1), 0.5)


def test_cube_limit_pinned():
    cube = unit_cube()
    np.testing.assert_allclose(limit_mesh(cube, 0).vertices, np.sign(cube.vertices) / 4, atol=1e-15)
    lim = limit_mesh(cube, 1)
    np.testing.assert_allclose(lim.vertices[:8], np.sign(cube.vertices) / 4, atol=1e-15)
    mid = cube.vertices[cube.topology.edges].mean(axis=1)
    np.testing.assert_allclose(lim.vertices[8:20], np.sign(mid) * 395 / 1296, atol=1e-15)
    np.testing.assert_allclose(lim.vertices[20:], np.sign(cube.face_centroids) * 34 / 81, atol=1e-15)
    for k in (2, 3):  # the same surface points stay put at every level
        deeper = limit_mesh(cube, k)
        np.testing.assert_allclose(deeper.vertices[:26], lim.vertices, atol=1e-14)


def test_refined_order_is_documented():
    """Vertex points, then edge points in edge order, then face points; quads per face in corner order."""
    mesh = MESHES["pentaprism"]
    topo = mesh.topology
    nv, ne = mesh.n_vertices, topo.n_edges
    cc = CatmullClark(mesh, 1)
    expected = []
    for f in range(mesh.n_faces):
        for h in range(mesh.offsets[f], mesh.offsets[f + 1]):
            expected.append((mesh.corners[h], nv + topo.he_edge[h], nv + ne + f, nv + topo.he_edge[topo.he_prev[h]]))
    assert cc.faces == expected
    assert cc.n_vertices == nv + ne + mesh.n_faces


# --- OpenSubdiv (lagrange) as oracle ------------------------------------------------------------------

OSD_BOUNDARY = {"all": "EdgeOnly", "corners": "EdgeAndCorner"}  # Blender's ALL / PRESERVE_CORNERS


def _canonical_faces(corners: np.ndarray, offsets: np.ndarray) -> set[tuple[int, ...]] | np.ndarray:
    """Faces as comparable rows: each rotated to start at its smallest index (orientation kept), sorted."""
    sizes = np.diff(offsets)
    if np.any(sizes != sizes[0]):
        return {tuple(np.roll(f, -int(np.argmin(f))).tolist()) for f in np.split(corners, offsets[1:-1])}
    a = corners.reshape(-1, sizes[0])
    rotated = np.take_along_axis(a, (np.argmin(a, axis=1)[:, None] + np.arange(sizes[0])) % sizes[0], axis=1)
    return rotated[np.lexsort(rotated.T[::-1])]


def match_meshes(ours: PolyMesh, theirs: PolyMesh, scale: float) -> float:
    """Max distance (over ``scale``) from our vertices to their nearest in ``theirs``; asserts that the
    nearest-neighbour map is a bijection carrying our faces (with orientation) onto theirs."""
    assert (ours.n_vertices, ours.n_faces) == (theirs.n_vertices, theirs.n_faces)
    dist, idx = cKDTree(theirs.vertices).query(ours.vertices)
    assert np.unique(idx).size == len(idx), "vertices do not match one to one"
    mapped = _canonical_faces(idx[ours.corners], ours.offsets)
    expected = _canonical_faces(theirs.corners, theirs.offsets)
    if isinstance(mapped, np.ndarray) and isinstance(expected, np.ndarray):
        assert mapped.shape == expected.shape and np.array_equal(mapped, expected), "faces differ"
    else:
        assert mapped == expected, "faces differ"
    return float(dist.max() / scale)


CASES = [(name, boundary) for name in MESHES for boundary in (("all", "corners") if name in OPEN else ("all",))]


@pytest.mark.parametrize("name,boundary", CASES)
def test_matches_opensubdiv(name, boundary):
    mesh = MESHES[name]
    for levels in (0, 1, 2, 3):
        cc = get_catmull_clark(mesh, levels, boundary)
        for limit in (False, True) if levels else (False,):  # level-0 limit: test_level_zero_limit
            ours = cc.limit(mesh.vertices) if limit else cc.refine(mesh.vertices)
            theirs = opensubdiv(mesh, levels, limit=limit, boundary=OSD_BOUNDARY[boundary])
            err = match_meshes(ours, theirs, mesh.diagonal)
            assert err < 1e-9, (levels, limit, err)


@pytest.mark.parametrize("name,boundary", CASES)
def test_level_zero_limit(name, boundary):
    """OpenSubdiv's level-0 limit applies the all-quad stencil even beside triangles and n-gons; the surface
    points are those of the level-1 vertex points (the first vertices in both orders), which we return."""
    mesh = MESHES[name]
    ours = limit_mesh(mesh, 0, boundary).vertices
    level1 = opensubdiv(mesh, 1, limit=True, boundary=OSD_BOUNDARY[boundary]).vertices
    np.testing.assert_allclose(ours, level1[: mesh.n_vertices], atol=1e-12)
    indptr, faces = mesh.topology.vertex_faces_csr
    all_quads = np.minimum.reduceat(mesh.face_sizes[faces] == 4, indptr[:-1]).astype(bool)
    level0 = opensubdiv(mesh, 0, limit=True, boundary=OSD_BOUNDARY[boundary]).vertices
    np.testing.assert_allclose(ours[all_quads], level0[all_quads], atol=1e-12)


@pytest.mark.parametrize("name", ["pyramid", "fan6"])
def test_refinement_converges_to_level_zero_limit(name):
    mesh = MESHES[name]
    target = limit_mesh(mesh, 0).vertices
    gaps = [np.abs(refine(mesh, k).vertices[: mesh.n_vertices] - target).max() for k in (2, 4, 6)]
    assert gaps[0] > gaps[1] > gaps[2] and gaps[2] < 1e-3 * mesh.diagonal
    assert gaps[2] < gaps[0] / 10


def test_boundary_modes_differ_only_at_corners():
    mesh = MESHES["grid"]
    a = limit_mesh(mesh, 2, "all").vertices
    b = limit_mesh(mesh, 2, "corners").vertices
    corners = [0, 3, 8, 11]
    np.testing.assert_array_equal(b[corners], mesh.vertices[corners])
    assert np.linalg.norm(a[corners] - mesh.vertices[corners], axis=1).min() > 0.05
    assert np.array_equal(limit_mesh(MESHES["cube"], 2, "all").vertices,
                          limit_mesh(MESHES["cube"], 2, "corners").vertices)


# --- scipy B-spline as oracle for boundary curves -----------------------------------------------------


def _bspline_points(ctrl: np.ndarray, params: np.ndarray) -> np.ndarray:
    """Uniform cubic B-spline with control point j centred on parameter j - 1 (ctrl[0] is a phantom)."""
    knots = np.arange(len(ctrl) + 4, dtype=float) - 3.0
    return BSpline(knots, ctrl, 3)(params)


@pytest.mark.parametrize("levels", [1, 2, 3])
def test_boundary_limit_is_the_cubic_bspline_of_the_boundary(levels):
    mesh = MESHES["grid"]
    loop = [0, 1, 2, 3, 7, 11, 10, 9, 8, 4]  # boundary polygon, corners at 0, 3, 11, 8
    p = mesh.vertices[loop]
    step = 2.0**-levels

    # "all": one closed (periodic) uniform cubic B-spline through the whole boundary loop
    ctrl = np.vstack([p[-1:], p, p[:2]])
    expected = _bspline_points(ctrl, np.arange(0, len(p), step))
    out = limit_mesh(mesh, levels, "all")
    got = out.vertices[out.topology.vertex_is_boundary]
    assert len(got) == len(expected)
    assert cKDTree(expected).query(got)[0].max() < 1e-12

    # "corners": one open spline per side, ends fixed (phantom points 2 P0 - P1 at both ends)
    expected = []
    for side in ([0, 1, 2, 3], [3, 4, 5], [5, 6, 7, 8], [8, 9, 0]):
        q = p[side]
        ctrl = np.vstack([2 * q[0] - q[1], q, 2 * q[-1] - q[-2]])
        expected.append(_bspline_points(ctrl, np.arange(0, len(q) - 1 + step / 2, step)))
    expected = np.unique(np.round(np.vstack(expected), 12), axis=0)
    out = limit_mesh(mesh, levels, "corners")
    got = out.vertices[out.topology.vertex_is_boundary]
    assert len(got) == len(expected)
    assert cKDTree(expected).query(got)[0].max() < 1e-12


# --- invariants ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("name,boundary", CASES)
def test_matrices_are_affine_and_nested(name, boundary):
    mesh = MESHES[name]
    previous = None
    for levels in range(4):
        cc = CatmullClark(mesh, levels, boundary)
        for m in (cc.refine_matrix, cc.limit_matrix):
            np.testing.assert_allclose(np.asarray(m.sum(axis=1)).ravel(), 1.0, atol=1e-13)
            assert m.shape == (cc.n_vertices, mesh.n_vertices)
        if previous is not None:  # level-k vertices are the first vertices of level k + 1, same limit points
            n = previous.n_vertices
            assert abs(cc.limit_matrix[:n] - previous.limit_matrix).max() < 1e-14
            assert np.all(cc.refine_matrix[:n].getnnz(axis=1) > 0)
        previous = cc


@settings(max_examples=25, deadline=None)
@given(name=st.sampled_from(sorted(MESHES)), boundary=st.sampled_from(sd.BOUNDARY_MODES),
       levels=st.integers(0, 2), seed=st.integers(0, 2**32 - 1), affine=st.lists(st.floats(-2, 2), min_size=12,
                                                                                    max_size=12))
def test_refinement_commutes_with_refining_and_affine_maps(name, boundary, levels, seed, affine):
    base = MESHES[name]
    noise = np.random.default_rng(seed).uniform(-0.1, 0.1, base.vertices.shape) * base.diagonal
    mesh = base.with_vertices(base.vertices + noise)
    once = refine(mesh, 1, boundary)
    # limit positions of a refined mesh are the limit positions of the original
    np.testing.assert_allclose(limit_mesh(mesh, levels + 1, boundary).vertices,
                               limit_mesh(once, levels, boundary).vertices, atol=1e-12 * mesh.diagonal)
    np.testing.assert_allclose(refine(mesh, levels + 1, boundary).vertices, refine(once, levels, boundary).vertices,
                               atol=1e-12 * mesh.diagonal)
    # affine invariance: subdividing the mapped mesh = mapping the subdivided mesh
    a = np.reshape(affine[:9], (3, 3)) + 3 * np.eye(3)
    t = np.asarray(affine[9:])
    moved = mesh.with_vertices(mesh.vertices @ a.T + t)
    for fn in (refine, limit_mesh):
        np.testing.assert_allclose(fn(moved, levels, boundary).vertices, fn(mesh, levels, boundary).vertices @ a.T + t,
                                   atol=1e-10 * (1 + np.abs(a).max()) * mesh.diagonal)


def test_refined_meshes_stay_valid_and_keep_euler_characteristic():
    for name, mesh in MESHES.items():
        chi = mesh.topology.euler_characteristic
        for levels in (1, 2):
            out = limit_mesh(mesh, levels)
            validate_mesh(out, require_closed=name not in OPEN, require_quads=True)
            assert out.topology.euler_characteristic == chi


def test_refined_topology_matches_a_sorted_one():
    """The refined topology, derived in closed form, is the one Topology builds by sorting the refined faces."""
    for name, mesh in MESHES.items():
        for levels in (1, 2):
            cc = CatmullClark(mesh, levels)
            fresh = Topology(cc.corners, cc.offsets, cc.n_vertices)
            for key, value in vars(fresh).items():
                np.testing.assert_array_equal(getattr(cc.topology, key), value, err_msg=f"{name} {levels} {key}")
            assert cc.limit(mesh.vertices).topology is cc.topology


def test_topology_input_and_level_zero():
    mesh = MESHES["inset_extruded"]
    a, b = CatmullClark(mesh, 2), CatmullClark(mesh.topology, 2)
    assert abs(a.refine_matrix - b.refine_matrix).max() == 0 and abs(a.limit_matrix - b.limit_matrix).max() == 0
    assert a.faces == b.faces
    zero = CatmullClark(mesh, 0)
    assert zero.faces == mesh.faces
    np.testing.assert_array_equal(zero.refine(mesh.vertices).vertices, mesh.vertices)


def test_triangles_fan_the_refined_faces_once_per_connectivity():
    for levels in (0, 2):
        cc = CatmullClark(MESHES["pentaprism"], levels)
        tris = cc.triangles
        assert tris is cc.triangles and not tris.flags.writeable
        np.testing.assert_array_equal(tris, triangulate(cc.corners, cc.offsets))
        assert len(tris) == int((np.diff(cc.offsets) - 2).sum())


def test_unused_vertex_stays_put():
    mesh = PolyMesh.from_faces(np.vstack([MESHES["cube"].vertices, [[5, 5, 5]]]), MESHES["cube"].faces)
    for fn in (refine, limit_mesh):
        out = fn(mesh, 2)
        np.testing.assert_array_equal(out.vertices[8], [5, 5, 5])
        np.testing.assert_allclose(out.vertices[:8], fn(MESHES["cube"], 2).vertices[:8], atol=1e-15)


# --- cache --------------------------------------------------------------------------------------------


def test_cache_is_keyed_by_topology():
    sd.clear_cache()
    cube = unit_cube()
    first = get_catmull_clark(cube, 3)
    moved = cube.with_vertices(cube.vertices * 2)
    rebuilt = PolyMesh.from_faces(cube.vertices + 1, cube.faces)
    assert get_catmull_clark(moved, 3) is first
    assert get_catmull_clark(rebuilt, 3) is first
    assert get_catmull_clark(cube, 3, "corners") is not first
    assert get_catmull_clark(cube, 2) is not first
    info = sd.cache_info()
    assert (info["hits"], info["misses"], info["entries"]) == (2, 3, 3)
    assert info["bytes"] > 0
    np.testing.assert_allclose(limit_mesh(moved, 3).vertices, 2 * limit_mesh(cube, 3).vertices, atol=1e-14)


def test_cache_evicts_least_recently_used():
    cache = sd._Cache(max_entries=2)
    meshes = [MESHES["cube"], MESHES["pyramid"], MESHES["torus"]]
    got = [cache.get(m, 1, "all") for m in meshes[:2]]
    assert cache.get(meshes[0], 1, "all") is got[0]  # cube is now the most recent
    cache.get(meshes[2], 1, "all")  # evicts the pyramid
    assert cache.info()["entries"] == 2
    assert cache.get(meshes[0], 1, "all") is got[0]
    assert cache.get(meshes[1], 1, "all") is not got[1]
    small = sd._Cache(max_bytes=1)
    small.get(meshes[0], 2, "all")
    assert small.info()["entries"] == 0
    # an entry is accounted at the size it had when stored, though the topology it shares may grow later
    one = sd._Cache(max_entries=1)
    cube = unit_cube()
    one.get(cube, 1, "all")
    cube.topology.vertex_valence, cube.topology.vertex_is_boundary, cube.topology.vertex_faces_csr
    torus = one.get(PolyMesh.from_faces(meshes[2].vertices, meshes[2].faces), 1, "all")  # evicts the cube's
    assert one.info()["bytes"] == torus.nbytes


# --- errors -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("levels", [-1, 1.5, True, "2"])
def test_bad_levels(levels):
    get_catmull_clark(unit_cube(), 1)  # a cached level-1 entry must not answer for True
    for build in (CatmullClark, get_catmull_clark):
        with pytest.raises(ConfigError, match="levels"):
            build(unit_cube(), levels)


def test_bad_arguments():
    with pytest.raises(ConfigError, match="boundary"):
        CatmullClark(unit_cube(), 1, "sharp")
    with pytest.raises(ConfigError, match="would make"):
        CatmullClark(unit_cube(), 14)
    with pytest.raises(InputError, match="PolyMesh"):
        CatmullClark(np.zeros((3, 3)), 1)
    with pytest.raises(InputError, match=r"\(8, 3\)"):
        get_catmull_clark(unit_cube(), 1).refine(np.zeros((7, 3)))
    with pytest.raises(TopologyError, match="without faces"):
        CatmullClark(PolyMesh(np.zeros((2, 3)), [], [0]), 1)
    bowtie = PolyMesh.from_faces([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], [[0, 1, 2], [0, 3, 4]])
    with pytest.raises(TopologyError, match="manifold"):
        CatmullClark(bowtie, 1)


# --- gsr subdivide ------------------------------------------------------------------------------------


def _write(path, text: str):
    path.write_text(text)
    return path


@pytest.mark.parametrize("limit", [False, True])
def test_cli_writes_a_valid_obj(gsr, tmp_path, limit):
    src = tmp_path / "in.obj"
    save_obj(MESHES["inset_extruded"], src)
    out = tmp_path / "out.obj"
    args = [src, "-o", out, "--levels", "2"] + (["--limit"] if limit else [])
    run = gsr("subdivide", *args)
    assert run.code == 0, run.err
    assert "wrote" in run.out and run.err == ""
    got = load_mesh(out)
    expected = (limit_mesh if limit else refine)(MESHES["inset_extruded"], 2)
    assert got.faces == expected.faces
    np.testing.assert_array_equal(got.vertices, expected.vertices)
    validate_mesh(got, require_closed=True, require_quads=True)


def test_cli_boundary_option(gsr, tmp_path):
    src = tmp_path / "grid.off"
    from gsr_cad.reconstruct.meshio import save_mesh

    save_mesh(MESHES["grid"], src)
    out = tmp_path / "g.obj"
    assert gsr("subdivide", src, "-o", out, "--levels", "1", "--limit", "--boundary", "corners").code == 0
    np.testing.assert_array_equal(load_mesh(out).vertices, limit_mesh(MESHES["grid"], 1, "corners").vertices)


BAD_INPUTS = {
    "nonmanifold.obj": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n", "non-manifold"),
    "unused.obj": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 9 9 9\nf 1 2 3\n", "not used"),
    "nan.obj": ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
    "repeat.obj": ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 2 3\n", "repeats vertex"),
    "empty.obj": ("", "empty"),
    "points.obj": ("v 0 0 0\nv 1 0 0\n", "no faces"),
    "mesh.xyz": ("0 0 0\n", "unsupported"),
}


@pytest.mark.parametrize("name", sorted(BAD_INPUTS))
def test_cli_rejects_bad_meshes(gsr, tmp_path, name):
    text, reason = BAD_INPUTS[name]
    out = tmp_path / "out.obj"
    run = gsr("subdivide", _write(tmp_path / name, text), "-o", out)
    assert run.code == 2
    assert run.err.startswith("error: ") and reason in run.err and run.err.count("\n") == 1
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_cli_rejects_bad_arguments(gsr, tmp_path):
    src = tmp_path / "in.obj"
    save_obj(MESHES["cube"], src)
    for args, reason in ((["--levels", "-2"], "levels"), (["--boundary", "x"], "invalid choice"),
                         (["-o", tmp_path / "x.step"], "cannot write"), (["--levels", "30"], "would make")):
        argv = [src, *args] if "-o" in args else [src, "-o", tmp_path / "o.obj", *args]
        run = gsr("subdivide", *argv)
        assert run.code == 2 and reason in run.err and run.err.count("\n") == 1
    assert gsr("subdivide", tmp_path / "missing.obj", "-o", tmp_path / "o.obj").code == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.obj"]


def test_cli_as_a_process(tmp_path):
    src = _write(tmp_path / "q.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    out = tmp_path / "q2.obj"
    proc = subprocess.run([sys.executable, "-m", "gsr_cad", "subdivide", str(src), "-o", str(out), "--levels", "3"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    got = load_mesh(out)
    assert got.n_faces == 64 and "wrote" in proc.stdout
    np.testing.assert_array_equal(got.vertices, refine(load_mesh(src), 3).vertices)


def test_kernel_benchmark_runs(tmp_path, capsys, monkeypatch):
    """The benchmark script stays runnable (no timing is asserted: speed belongs to benchmarks/)."""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "kernel.py"
    spec = importlib.util.spec_from_file_location("kernel_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)  # dataclasses look their module up there
    spec.loader.exec_module(module)
    out = tmp_path / "kernel.md"
    assert module.main(["--quick", "--out", str(out)]) == 0
    table = out.read_text()
    assert table.count("| subdivision | cube | 6 |") == 3 and "| subdivision | torus 8x4 | 32 |" in table
    assert table.count("| fit | torus 16x8 | 128 |") == 5 and table.count("| fit | cube split 2x | 96 |") == 5
    with pytest.raises(SystemExit):
        module.main(["--sections", "nope", "--out", str(out)])
