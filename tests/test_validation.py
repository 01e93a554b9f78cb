"""Mesh validation: every bad case gets its one-line reason; mesh_report counts against known meshes and
vertex_fans against Topology's own fan walk."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import torus
from hypothesis import given, settings
from hypothesis import strategies as st

from gsr_cad.errors import InputError, TopologyError
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.geometry.topology import Topology
from gsr_cad.geometry.validation import mesh_report, validate_mesh, vertex_fans

CUBE = unit_cube()
TRI = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


def grid(nx: int, ny: int) -> PolyMesh:
    v = [[x, y, 0.0] for y in range(ny) for x in range(nx)]
    faces = [[y * nx + x, y * nx + x + 1, (y + 1) * nx + x + 1, (y + 1) * nx + x]
             for y in range(ny - 1) for x in range(nx - 1)]
    return PolyMesh.from_faces(v, faces)


def flipped_cube() -> PolyMesh:
    faces = CUBE.faces
    faces[2] = faces[2][::-1]
    return PolyMesh.from_faces(CUBE.vertices, faces)


def with_vertex(mesh: PolyMesh, index: int, value) -> PolyMesh:
    v = mesh.vertices.copy()
    v[index] = value
    return PolyMesh(v, mesh.corners, mesh.offsets)


BAD = {
    "no vertices": (PolyMesh(np.zeros((0, 3)), [], [0]), "empty"),
    "no faces": (PolyMesh(np.zeros((3, 3)), [], [0]), "no faces"),
    "nan": (with_vertex(CUBE, 3, [np.nan, 0, 0]), "vertex 3 has a NaN or infinite"),
    "inf": (with_vertex(CUBE, 5, [0, np.inf, 0]), "vertex 5 has a NaN or infinite"),
    "repeated (apart)": (PolyMesh.from_faces(TRI + [[1, 1, 0]], [[0, 1, 3, 1, 2]]), "face 0 repeats vertex 1"),
    "repeated (adjacent)": (PolyMesh.from_faces(TRI, [[0, 1, 1, 2]]), "face 0 repeats vertex 1"),
    "unreferenced": (PolyMesh.from_faces(TRI + [[5, 5, 5]], [[0, 1, 2]]), "vertex 3 is not used"),
    "non-manifold edge": (PolyMesh.from_faces(TRI + [[0, -1, 0], [0, 0, 1]], [[0, 1, 2], [1, 0, 3], [0, 1, 4]]),
                          "edge (0, 1) is shared by 3 faces"),
    "orientation": (flipped_cube(), "inconsistent orientation"),
    "bowtie vertex": (PolyMesh.from_faces(TRI + [[-1, 0, 0], [0, -1, 0]], [[0, 1, 2], [0, 3, 4]]),
                      "vertex 0 is non-manifold (2 separate fans"),
    "two cones": (PolyMesh.from_faces(
        [[0, 0, 0], [1, 0, 1], [0, 1, 1], [-1, -1, 1], [1, 0, -1], [0, 1, -1], [-1, -1, -1]],
        [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2], [0, 5, 4], [0, 6, 5], [0, 4, 6], [4, 5, 6]]),
        "vertex 0 is non-manifold"),
    "collinear triangle": (PolyMesh.from_faces(TRI + [[2, 0, 0]], [[0, 1, 2], [0, 3, 1]]), "face 1 has zero area"),
    "collapsed quad": (PolyMesh.from_faces([[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 0]], [[0, 1, 2, 3]]),
                       "face 0 has zero area"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_meshes_raise_one_line(case):
    mesh, reason = BAD[case]
    with pytest.raises(TopologyError) as info:
        validate_mesh(mesh)
    message = str(info.value)
    assert reason in message and "\n" not in message
    assert isinstance(info.value, InputError)
    report = mesh_report(mesh)  # never raises; agrees with validate_mesh
    assert report["valid"] is False and report["problem"] == message


def test_requirements():
    open_cube = PolyMesh.from_faces(CUBE.vertices, CUBE.faces[:5])
    assert validate_mesh(open_cube) is open_cube
    with pytest.raises(TopologyError, match="mesh is open: 4 boundary edges"):
        validate_mesh(open_cube, require_closed=True)
    pyramid = PolyMesh.from_faces([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]],
                                  [[3, 2, 1, 0], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    assert validate_mesh(pyramid, require_closed=True) is pyramid
    with pytest.raises(TopologyError, match="face 1 has 3 corners; only quads"):
        validate_mesh(pyramid, require_quads=True)
    validate_mesh(torus(), require_closed=True, require_quads=True)


def test_with_vertices_shares_the_connectivity_and_checks_the_count():
    mesh = torus()
    topo, key = mesh.topology, mesh.topology_key
    moved = mesh.with_vertices((2 * mesh.vertices).tolist())
    assert moved.topology is topo and moved.topology_key is key
    assert moved.corners is mesh.corners and moved.offsets is mesh.offsets
    np.testing.assert_array_equal(moved.vertices, 2 * mesh.vertices)
    assert moved.vertices.dtype == np.float64 and not moved.vertices.flags.writeable
    with pytest.raises(TopologyError, match="as many vertices"):
        mesh.with_vertices(mesh.vertices[:-1])


def test_tiny_but_proper_faces_pass():
    small = CUBE.with_vertices(CUBE.vertices * 1e-9)
    validate_mesh(small)
    sliver = PolyMesh.from_faces(TRI + [[2, 1e-5, 0]], [[0, 1, 2], [0, 3, 1]])
    validate_mesh(sliver)


KNOWN = {
    "cube": (CUBE, dict(vertices=8, edges=12, faces=6, quads=6, euler_characteristic=2, genus=0, closed=True,
                        boundary_edges=0, components=1)),
    "torus": (torus(), dict(vertices=24, edges=48, faces=24, euler_characteristic=0, genus=1, closed=True)),
    "open cube": (PolyMesh.from_faces(CUBE.vertices, CUBE.faces[:5]),
                  dict(edges=12, boundary_edges=4, euler_characteristic=1, closed=False, genus=None)),
    "grid": (grid(4, 3), dict(vertices=12, faces=6, edges=17, boundary_edges=10, euler_characteristic=1)),
    "two cubes": (PolyMesh.from_faces(np.vstack([CUBE.vertices, CUBE.vertices + 3]),
                                      CUBE.faces + [tuple(i + 8 for i in f) for f in CUBE.faces]),
                  dict(components=2, euler_characteristic=4, closed=True, genus=None, valid=True)),
    "pentagon and triangle": (PolyMesh.from_faces([[0, 0, 0], [1, 0, 0], [1.5, 1, 0], [0.5, 1.6, 0], [-0.5, 1, 0],
                                                   [2, 0, 0]], [[0, 1, 2, 3, 4], [1, 5, 2]]),
                              dict(triangles=1, quads=0, ngons=1, edges=7, boundary_edges=6)),
}


@pytest.mark.parametrize("name", sorted(KNOWN))
def test_mesh_report_known_meshes(name):
    mesh, expected = KNOWN[name]
    report = mesh_report(mesh)
    assert {k: report[k] for k in expected} == expected
    assert report["manifold"] and report["oriented"]
    if report["valid"]:
        assert report["problem"] is None
        assert report["euler_characteristic"] == mesh.topology.euler_characteristic
        assert mesh.topology.is_manifold


def test_mesh_report_counts_creases():
    cube = unit_cube()
    assert (mesh_report(cube)["creased_edges"], mesh_report(cube)["sharp_edges"]) == (0, 0)
    report = mesh_report(cube.with_creases({(4, 5): 10.0, (5, 7): 2.0, (0, 1): 12.0}))
    assert (report["creased_edges"], report["sharp_edges"]) == (3, 2) and report["valid"]


def test_mesh_report_flags():
    assert mesh_report(flipped_cube())["oriented"] is False
    assert mesh_report(BAD["bowtie vertex"][0])["manifold"] is False
    assert mesh_report(BAD["non-manifold edge"][0])["manifold"] is False
    assert mesh_report(BAD["unreferenced"][0])["unreferenced_vertices"] == 1
    empty = mesh_report(PolyMesh(np.zeros((0, 3)), [], [0]))
    assert (empty["vertices"], empty["edges"], empty["components"], empty["valid"]) == (0, 0, 0, False)


def walked_fans(topo: Topology) -> np.ndarray:
    """Fans per vertex by walking ``h -> twin(prev(h))`` one half-edge at a time (an independent oracle):
    open fans from their outgoing boundary half-edge, then the closed ones from any unseen corner."""
    seen = np.zeros(len(topo.he_origin), dtype=bool)
    fans = np.zeros(topo.n_vertices, dtype=np.int64)
    for h in [*np.flatnonzero(topo.he_twin < 0), *range(len(topo.he_origin))]:
        if seen[h]:
            continue
        fans[topo.he_origin[h]] += 1
        while h >= 0 and not seen[h]:
            seen[h] = True
            h = topo.he_twin[topo.he_prev[h]]
    return fans


@settings(max_examples=40, deadline=None)
@given(keep=st.lists(st.booleans(), min_size=24, max_size=24), seed=st.integers(0, 2**32 - 1))
def test_vertex_fans_agree_with_topology_walk(keep, seed):
    """Dropping faces of a torus makes bowtie vertices; vertex_fans must agree with a plain fan walk and with
    Topology.is_manifold."""
    base = torus()
    faces = [f for f, k in zip(base.faces, keep, strict=True) if k]
    if not faces:
        return
    perm = np.random.default_rng(seed).permutation(len(faces))  # face order must not matter
    mesh = PolyMesh.from_faces(base.vertices, [faces[i] for i in perm])
    topo = Topology(mesh.corners, mesh.offsets, mesh.n_vertices)
    fans = vertex_fans(topo)
    assert np.array_equal(fans, walked_fans(topo))
    assert np.array_equal(fans > 0, np.bincount(mesh.corners, minlength=mesh.n_vertices) > 0)
    assert bool(np.all(fans <= 1)) == topo.is_manifold
    report = mesh_report(mesh)
    assert report["manifold"] == topo.is_manifold
    used = np.unique(mesh.corners).size
    assert report["euler_characteristic"] == used - topo.n_edges + topo.n_faces


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_report_is_invariant_under_relabelling(seed):
    rng = np.random.default_rng(seed)
    base = torus()
    perm = rng.permutation(base.n_vertices)
    inverse = np.argsort(perm)
    faces = [[int(inverse[i]) for i in np.roll(f, rng.integers(4))] for f in base.faces]
    mesh = PolyMesh.from_faces(base.vertices[perm], [faces[i] for i in rng.permutation(len(faces))])
    assert mesh_report(mesh) == mesh_report(base)
