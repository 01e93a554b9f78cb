"""The seven surface ops: hand-checked geometry on the cube, independent oracles (numpy Newell normals,
Topology, trimesh volumes, point-line distances), invariants over random genomes, JSON, and errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from gsr_cad import genome as genome_mod
from gsr_cad.errors import ConfigError, InputError, OpError, TopologyError
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.ops.base import op_from_json
from gsr_cad.ops.curve import MovePoint
from gsr_cad.ops.mesh import (OPS_BY_LETTER, PAPER_RANGES, Bevel, EdgeLoop, Extrude, Inset, OpRanges, Scale,
                              TranslateFace, TranslateVertex, bevel, edge_loop, extrude, inset, perturb_op,
                              random_op, scale, translate_face, translate_vertex)
from gsr_cad.ops.mesh_conn import MeshConn, connectivity
from gsr_cad.ops.mesh_kernel import edge_ring

CUBE = unit_cube()
D = CUBE.diagonal


def volume(mesh: PolyMesh) -> float:
    """Enclosed volume by trimesh (faces fanned from their first corner; exact for planar convex faces)."""
    tris = [(f[0], f[i], f[i + 1]) for f in mesh.faces for i in range(1, len(f) - 1)]
    return float(trimesh.Trimesh(mesh.vertices, tris, process=False).volume)


def edge_index(mesh: PolyMesh, u: int, v: int) -> int:
    edges = mesh.topology.edges
    return int(np.flatnonzero(((edges[:, 0] == u) & (edges[:, 1] == v)) | ((edges[:, 0] == v) & (edges[:, 1] == u)))[0])


def line_distance(p, a, b) -> float:
    p, a, b = map(np.asarray, (p, a, b))
    d = (b - a) / np.linalg.norm(b - a)
    return float(np.linalg.norm(np.cross(p - a, d)))


def assert_sound(mesh: PolyMesh) -> None:
    topo = mesh.topology  # raises on inconsistent orientation or a non-manifold edge
    assert topo.is_closed and topo.is_manifold
    assert topo.euler_characteristic == 2
    assert mesh.face_areas.min() > 1e-9
    assert np.count_nonzero(topo.vertex_valence) == mesh.n_vertices  # no stray vertex


# --- hand-checked geometry on the unit cube -------------------------------------------------------------

def test_extrude_cube_face():
    m = extrude(CUBE, 1, 0.5)
    assert (m.n_vertices, m.n_faces) == (12, 10)
    assert volume(m) == pytest.approx(1.5)
    np.testing.assert_allclose(m.vertices[8:], CUBE.vertices[[1, 3, 7, 5]] + [0.5, 0, 0])
    assert m.faces[1] == (8, 9, 10, 11)
    assert m.faces[6:] == [(1, 3, 9, 8), (3, 7, 10, 9), (7, 5, 11, 10), (5, 1, 8, 11)]
    assert m.faces[:1] + m.faces[2:6] == CUBE.faces[:1] + CUBE.faces[2:]
    assert_sound(m)


def test_bevel_cube_edge_gives_pentagon_ends():
    m = bevel(CUBE, 0, 0.2)  # edge 0 runs 0 -> 4 along z at x = y = -0.5; faces -x (first) and -y
    assert (m.n_vertices, m.n_faces) == (10, 7)
    assert sorted(len(f) for f in m.faces) == [4, 4, 4, 4, 4, 5, 5]
    assert volume(m) == pytest.approx(1 - 0.2 ** 2 / 2)
    np.testing.assert_allclose(m.vertices[[0, 4, 8, 9]],
                               [[-.5, -.3, -.5], [-.5, -.3, .5], [-.3, -.5, -.5], [-.3, -.5, .5]])
    assert m.faces[6] == (0, 8, 9, 4)
    assert (m.faces[4], m.faces[5]) == ((8, 0, 2, 3, 1), (4, 9, 5, 7, 6))
    np.testing.assert_allclose(m.face_normals[6], [-math.sqrt(0.5), -math.sqrt(0.5), 0], atol=1e-12)
    assert_sound(m)


def test_bevel_valence_four_end_gets_a_polygon():
    base = extrude(CUBE, 1, 0.5)  # the old +x rim now has valence 4
    e = edge_index(base, 1, 3)
    assert tuple(base.topology.edges[e]) == (3, 1)  # end a = 3 (y = +0.5), end b = 1 (y = -0.5)
    m = bevel(base, e, 0.1)
    assert (m.n_vertices, m.n_faces) == (16, 13)
    assert [m.faces[11][0], m.faces[12][0]] == [3, 1]  # end polygons start at the vertex keeping the end's index
    for face, y in ((m.faces[11], 0.5), (m.faces[12], -0.5)):
        ring = {tuple(p) for p in np.round(m.vertices[list(face)], 12).tolist()}
        assert ring == {(0.4, y, -0.5), (0.6, y, -0.5), (0.5, y, -0.4)}  # meet, meet, slid 0.1 along +z
    assert volume(m) == pytest.approx(1.5)  # the edge is flat: the bevel only cuts the surface
    assert_sound(m)


def test_inset_cube_face():
    m = inset(CUBE, 1, 0.2)
    assert (m.n_vertices, m.n_faces) == (12, 10)
    np.testing.assert_allclose(m.vertices[8:], [[.5, -.3, -.3], [.5, .3, -.3], [.5, .3, .3], [.5, -.3, .3]])
    assert m.faces[1] == (8, 9, 10, 11)
    assert m.faces[6:] == [(1, 3, 9, 8), (3, 7, 10, 9), (7, 5, 11, 10), (5, 1, 8, 11)]
    assert volume(m) == pytest.approx(1.0)
    assert_sound(m)


def test_edge_loop_around_the_cube():
    m = edge_loop(CUBE, 0)
    assert (m.n_vertices, m.n_faces) == (12, 10)
    assert all(len(f) == 4 for f in m.faces)
    np.testing.assert_allclose(m.vertices[8:, 2], 0.0)
    new = {tuple(p) for p in m.vertices[8:].tolist()}
    assert new == {(-.5, -.5, 0.0), (-.5, .5, 0.0), (.5, .5, 0.0), (.5, -.5, 0.0)}
    assert m.faces[4:6] == CUBE.faces[4:6]  # the caps are not crossed
    assert volume(m) == pytest.approx(1.0)
    assert_sound(m)


def test_edge_loop_ends_in_t_vertices_at_pentagons():
    b = bevel(CUBE, 0, 0.2)
    m = edge_loop(b, edge_index(b, 0, 8))  # a short edge of the bevel quad: the ring is that quad alone
    assert (m.n_vertices, m.n_faces) == (12, 8)
    assert sorted(len(f) for f in m.faces) == [4, 4, 4, 4, 4, 4, 6, 6]
    np.testing.assert_allclose(m.vertices[10], (b.vertices[0] + b.vertices[8]) / 2)
    assert_sound(m)


def test_translate_face_scale_and_vertex():
    m = translate_face(CUBE, 1, 0.3)
    np.testing.assert_allclose(m.vertices[[1, 3, 5, 7], 0], 0.8)
    assert volume(m) == pytest.approx(1.3)
    off = unit_cube(center=(1.0, 2.0, 3.0))
    s = scale(off, 2.0)
    np.testing.assert_allclose(s.vertices, (off.vertices - [1, 2, 3]) * 2 + [1, 2, 3])
    assert volume(s) == pytest.approx(8.0)
    v = translate_vertex(CUBE, 7, (0.1, -0.2, 0.05))
    np.testing.assert_allclose(v.vertices[7], [0.6, 0.3, 0.55])
    np.testing.assert_array_equal(np.delete(v.vertices, 7, 0), np.delete(CUBE.vertices, 7, 0))


def test_vertex_moves_share_the_built_topology():
    mesh = unit_cube()
    topo = mesh.topology
    for op in (TranslateVertex(2, (0.1, 0, 0)), TranslateFace(3, 0.1), Scale(1.2)):
        out = op.apply(mesh)
        assert out.topology is topo and out.topology_key == mesh.topology_key


# --- independent oracles on skewed meshes ---------------------------------------------------------------

def test_inset_puts_inner_edges_at_the_thickness_on_a_planar_skewed_face():
    rng = np.random.default_rng(3)
    for _ in range(20):
        verts = CUBE.vertices.copy()
        verts[[1, 3, 5, 7], 1:] += rng.uniform(-0.15, 0.15, (4, 2))  # the +x face stays in the plane x = 0.5
        mesh = PolyMesh.from_faces(verts, CUBE.faces)
        t = rng.uniform(0.02, 0.15)
        m = inset(mesh, 1, t)
        outer, inner = mesh.faces[1], m.faces[1]
        for i in range(4):
            a, b = mesh.vertices[outer[i]], mesh.vertices[outer[(i + 1) % 4]]
            p, q = m.vertices[inner[i]], m.vertices[inner[(i + 1) % 4]]
            assert line_distance(p, a, b) == pytest.approx(t, abs=1e-12)
            assert line_distance(q, a, b) == pytest.approx(t, abs=1e-12)
        assert_sound(m)


def test_bevel_points_lie_on_the_old_edges_at_the_offset():
    rng = np.random.default_rng(4)
    checked = 0
    for _ in range(40):
        mesh = PolyMesh.from_faces(CUBE.vertices + rng.uniform(-0.12, 0.12, (8, 3)), CUBE.faces)
        e = int(rng.integers(12))
        a, b = mesh.topology.edges[e]
        d = rng.uniform(0.02, 0.2)
        try:
            m = bevel(mesh, e, d)
        except OpError:
            continue
        for end, other, new in ((a, b, [a, 8]), (b, a, [b, 9])):
            for p in m.vertices[new]:
                # each boundary point lies on an old edge (end, x) and d from the bevelled edge's line
                nbrs = [x for x in set(mesh.topology.edges[(mesh.topology.edges == end).any(1)].ravel()) - {end, other}]
                assert min(line_distance(p, mesh.vertices[end], mesh.vertices[x]) for x in nbrs) < 1e-12
                assert line_distance(p, mesh.vertices[a], mesh.vertices[b]) == pytest.approx(d, abs=1e-12)
        assert_sound(m)
        checked += 1
    assert checked >= 30


def test_extrude_and_translate_face_follow_the_newell_normal():
    rng = np.random.default_rng(5)
    for _ in range(20):
        mesh = PolyMesh.from_faces(CUBE.vertices + rng.uniform(-0.1, 0.1, (8, 3)), CUBE.faces)
        f = int(rng.integers(6))
        d = rng.uniform(0.1, 0.5)
        n = mesh.face_normals[f]
        m = extrude(mesh, f, d)
        np.testing.assert_allclose(m.vertices[8:], mesh.vertices[list(mesh.faces[f])] + d * n, atol=1e-14)
        t = translate_face(mesh, f, -0.05)
        np.testing.assert_allclose(t.vertices[list(mesh.faces[f])], mesh.vertices[list(mesh.faces[f])] - 0.05 * n,
                                   atol=1e-14)


# --- invariants over random genomes ---------------------------------------------------------------------

def _check_order(op, before: PolyMesh, after: PolyMesh) -> None:
    """The element order each op documents."""
    n, m = before.n_vertices, before.n_faces
    if isinstance(op, (TranslateVertex, TranslateFace, Scale)):
        np.testing.assert_array_equal(after.corners, before.corners)
        np.testing.assert_array_equal(after.offsets, before.offsets)
    if isinstance(op, (Extrude, Inset)):
        k = len(before.faces[op.face])
        c = before.faces[op.face]
        assert after.n_vertices == n + k and after.n_faces == m + k
        assert after.faces[op.face] == tuple(range(n, n + k))
        assert after.faces[m:] == [(c[i], c[(i + 1) % k], n + (i + 1) % k, n + i) for i in range(k)]
        np.testing.assert_array_equal(after.vertices[:n], before.vertices)
    if isinstance(op, Extrude):
        expect = before.vertices[list(c)] + op.distance * before.face_normals[op.face]
        np.testing.assert_allclose(after.vertices[n:], expect, atol=1e-12)
    if isinstance(op, EdgeLoop):
        np.testing.assert_array_equal(after.vertices[:n], before.vertices)
        e = before.topology.edges
        mids = (before.vertices[e[:, 0]] + before.vertices[e[:, 1]]) / 2
        for p in after.vertices[n:]:
            assert np.min(np.abs(mids - p).max(axis=1)) < 1e-12
        ring, quads, _, closed = edge_ring(connectivity(before), op.edge)
        assert after.n_vertices - n == len(ring) and after.n_faces - m == len(quads)
        assert len(quads) == (len(ring) if closed else len(ring) - 1)
        untouched = [f for f in range(m) if max(after.faces[f]) < n]
        assert all(after.faces[f] == before.faces[f] for f in untouched)
    if isinstance(op, Bevel):
        a, b = before.topology.edges[op.edge]
        val = before.topology.vertex_valence
        assert after.n_vertices == n + (val[a] - 2) + (val[b] - 2)
        assert after.n_faces == m + 1 + (val[a] >= 4) + (val[b] >= 4)
        keep = np.setdiff1d(np.arange(n), [a, b])
        np.testing.assert_array_equal(after.vertices[keep], before.vertices[keep])


def _check_conn(mesh: PolyMesh) -> None:
    """The cached plain-Python connectivity (patched op by op) equals a fresh build and Topology."""
    cached, fresh = connectivity(mesh), MeshConn(mesh.faces, mesh.n_vertices)
    assert cached.half == fresh.half
    np.testing.assert_array_equal(np.array(cached.edges), mesh.topology.edges)
    np.testing.assert_array_equal(np.array([cached.edge_faces(e) for e in range(len(cached.edges))]),
                                  mesh.topology.edge_faces)


def seeded_genomes(count: int, base: tuple, kinds: str, draws: int, keep, first_seed: int = 0) -> list[tuple]:
    """``count`` genomes: ``base`` on the unit cube, then ``draws`` random ops of ``kinds`` (those that apply kept),
    one ``numpy`` seed per try from ``first_seed`` on; a try is kept when ``keep(ops, mesh)`` holds."""
    out = []
    seed = first_seed
    while len(out) < count:
        rng = np.random.default_rng(seed)
        seed += 1
        state = genome_mod.replay(unit_cube(), base)
        ops = list(base)
        for _ in range(draws):
            op = random_op(rng, state, state.diagonal, kinds)
            try:
                state = op.apply(state)
            except OpError:
                continue
            ops.append(op)
        if keep(ops, state):
            out.append(tuple(ops))
    return out


def random_history(seed: int, length: int, kinds: str, sound: bool = True):
    """Up to ``length`` valid random ops on the cube, tried ``4 * length`` times: ``(op, before, after)`` each
    (each result checked by :func:`assert_sound` with ``sound``)."""
    rng = np.random.default_rng(seed)
    state, kept = CUBE, 0
    for _ in range(4 * length):
        if kept == length:
            return
        op = random_op(rng, state, D, kinds)
        assert op.letter in kinds
        try:
            after = op.apply(state)
        except OpError:
            continue
        if sound:
            assert_sound(after)
        yield op, state, after
        kept += 1
        state = after


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), length=st.integers(1, 8),
       kinds=st.sampled_from(["VELBIFS", "LB", "EIL", "VBF", "BBLLE"]))
def test_random_genomes_keep_a_sound_closed_mesh(seed, length, kinds):
    state, ops = CUBE, []
    for op, state, after in random_history(seed, length, kinds):
        _check_order(op, state, after)
        _check_conn(after)
        again = op.apply(state)
        np.testing.assert_array_equal(again.vertices, after.vertices)
        np.testing.assert_array_equal(again.corners, after.corners)
        ops.append(op)
        state = after
    genome = tuple(ops)
    text = json.dumps(genome_mod.to_json(genome))
    back = genome_mod.from_json(json.loads(text))
    assert back == genome and hash(back) == hash(genome)
    replayed = genome_mod.replay(unit_cube(), back)
    np.testing.assert_array_equal(replayed.vertices, state.vertices)
    assert replayed.faces == state.faces


def test_connectivity_rejects_non_manifold_input():
    mesh = PolyMesh.from_faces(np.eye(4)[:, :3], [(0, 1, 2), (0, 1, 3)])
    with pytest.raises(TopologyError):
        connectivity(mesh)


# --- invalid ops ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("op", [
    TranslateVertex(8, (0.1, 0, 0)), Extrude(6, 0.1), EdgeLoop(12), Bevel(12, 0.1), Inset(6, 0.1),
    TranslateFace(6, 0.1),
    Extrude(1, 0.0),                       # zero-height side faces
    Extrude(1, -0.3),                      # side faces fold back onto their neighbours
    Inset(1, 0.5), Inset(1, 0.7),          # the inner face vanishes or turns inside out
    Bevel(0, 1.0), Bevel(0, 1.5),          # the offset runs past the adjacent edges
    TranslateVertex(0, (1.2, 0.3, 0.3)),   # a corner pushed through the cube
    TranslateFace(1, -1.0),                # a face moved onto the opposite one
], ids=lambda op: op.describe())
def test_invalid_ops_raise_op_error(op):
    with pytest.raises(OpError):
        op.apply(CUBE)


def test_edge_loop_needs_a_quad_and_bevel_a_clear_corner():
    tetra = PolyMesh.from_faces([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]],
                                [(0, 1, 2), (0, 3, 1), (0, 2, 3), (1, 3, 2)])
    assert_sound(tetra)
    with pytest.raises(OpError, match="no quad"):
        edge_loop(tetra, 0)
    b = bevel(CUBE, 0, 0.2)
    t = edge_loop(b, edge_index(b, 0, 8))  # T-vertex 10 lies on the straight old edge 0-8
    with pytest.raises(OpError, match="too flat"):
        bevel(t, edge_index(t, 10, 0), 0.05)
    with pytest.raises(OpError, match="positive"):
        scale(CUBE, -1.0)


def test_ops_reject_malformed_parameters():
    for bad in (lambda: TranslateVertex(-1, (0, 0, 0)), lambda: TranslateVertex(True, (0, 0, 0)),
                lambda: TranslateVertex(0, (0, 0)), lambda: TranslateVertex(0, (0, math.nan, 0)),
                lambda: Extrude(1.5, 0.1), lambda: Extrude(0, math.inf), lambda: Extrude(0, "far"),
                lambda: Bevel(0, 0.0), lambda: Bevel(0, -0.1), lambda: Inset(0, -1.0), lambda: Scale(0.0),
                lambda: EdgeLoop("3")):
        with pytest.raises(InputError):
            bad()
    with pytest.raises(InputError, match="bevel offset must be a finite positive number"):
        Bevel(0, 0.0)
    with pytest.raises(InputError, match="translate_vertex delta must be three numbers"):
        TranslateVertex(0, (0, 0))
    with pytest.raises(InputError):
        op_from_json({"op": "bevel", "edge": 1})
    op = op_from_json({"op": "extrude", "face": 2.0, "distance": 1})
    assert op == Extrude(2, 1.0) and type(op.face) is int and type(op.distance) is float
    v = TranslateVertex(np.int64(3), np.array([1, 2, -0.0]))
    assert v.vertex == 3 and type(v.vertex) is int and v.delta == (1.0, 2.0, 0.0)
    assert all(type(x) is float for x in v.delta) and math.copysign(1.0, v.delta[2]) == 1.0


# --- random_op and perturb_op ---------------------------------------------------------------------------

def test_random_op_ranges():
    rng = np.random.default_rng(0)
    r = OpRanges()
    seen = set()
    for _ in range(700):
        op = random_op(rng, CUBE, D)
        seen.add(op.letter)
        if isinstance(op, TranslateVertex):
            assert 0 <= op.vertex < 8 and max(map(abs, op.delta)) <= r.move * D
        elif isinstance(op, Extrude):
            assert 0.05 * r.extrude * D <= abs(op.distance) <= r.extrude * D and 0 <= op.face < 6
        elif isinstance(op, TranslateFace):
            assert abs(op.distance) <= r.face_move * D
        elif isinstance(op, Scale):
            assert 1 / r.max_factor <= op.factor <= r.max_factor
        elif isinstance(op, Bevel):
            assert r.offset[0] <= op.offset <= r.offset[1] and 0 <= op.edge < 12  # cube edges have length 1
        elif isinstance(op, Inset):
            assert r.thickness[0] * 0.5 <= op.thickness <= r.thickness[1] * 0.5
        else:
            assert 0 <= op.edge < 12
    assert seen == set(OPS_BY_LETTER)
    paper = [random_op(rng, CUBE, D, "V", ranges=PAPER_RANGES).delta for _ in range(200)]
    assert np.abs(paper).max() > 0.5 * D


def test_random_op_rejects_bad_arguments():
    rng = np.random.default_rng(0)
    for kinds in ("", "VQ", "v"):
        with pytest.raises(ConfigError):
            random_op(rng, CUBE, D, kinds)
    for bad_scale in (0.0, -1.0, math.nan):
        with pytest.raises(ConfigError):
            random_op(rng, CUBE, bad_scale)
    with pytest.raises(ConfigError):
        OpRanges(offset=(0.5, 0.1))
    with pytest.raises(ConfigError):
        OpRanges(inward=2.0)


def test_perturb_op_keeps_kind_and_element():
    rng = np.random.default_rng(1)
    ops = [TranslateVertex(3, (0.1, 0.0, -0.1)), Extrude(2, 0.4), TranslateFace(1, -0.1), Bevel(5, 0.1),
           Inset(4, 0.05), Scale(1.1), EdgeLoop(7)]
    for op in ops:
        for _ in range(50):
            p = perturb_op(op, rng, D)
            assert type(p) is type(op)
            assert [getattr(p, f) for f in ("vertex", "face", "edge") if hasattr(p, f)] == \
                   [getattr(op, f) for f in ("vertex", "face", "edge") if hasattr(op, f)]
            if isinstance(op, TranslateVertex):
                assert 0 < np.abs(np.subtract(p.delta, op.delta)).max() < 10 * 0.02 * D
            elif isinstance(op, (Extrude, TranslateFace)):
                assert 0 < abs(p.distance - op.distance) < 10 * 0.02 * D
            elif isinstance(op, Bevel):
                assert p.offset > 0 and abs(math.log(p.offset / op.offset)) < 0.6
            elif isinstance(op, Inset):
                assert p.thickness > 0 and abs(math.log(p.thickness / op.thickness)) < 0.6
            elif isinstance(op, Scale):
                assert abs(math.log(p.factor / op.factor)) < 0.2
            else:
                assert p == op
    with pytest.raises(InputError):
        perturb_op(MovePoint(1, (0.0, 0.0)), rng, D)
    with pytest.raises(ConfigError):
        perturb_op(ops[0], rng, 0.0)
