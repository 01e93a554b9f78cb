"""The crease op C and how creases travel through the other surface ops (V E L B I F S)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mesh_ops import random_history

from gsr_cad import genome as genome_mod
from gsr_cad.errors import ConfigError, InputError, OpError
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.geometry.subdivision import get_catmull_clark
from gsr_cad.ops.mesh import (ALL_OPS_BY_LETTER, OPS_BY_LETTER, Crease, CreaseRim, OpRanges, bevel, crease, crease_rim,
                              edge_loop, extrude, inset, perturb_op, random_op, scale, translate_face, translate_vertex)

CUBE = unit_cube()
D = CUBE.diagonal
TOP = {(4, 5): 10.0, (5, 7): 10.0, (6, 7): 10.0, (4, 6): 10.0}  # the rim of face 5 (+z)


def _edge(mesh: PolyMesh, a: int, b: int) -> int:
    return [tuple(sorted(e)) for e in mesh.topology.edges.tolist()].index((min(a, b), max(a, b)))


def test_crease_op_sets_and_clears_sharpness():
    m = crease(CUBE, _edge(CUBE, 4, 5), 2.5)
    assert m.creases == {(4, 5): 2.5}
    assert m.connectivity_key == CUBE.connectivity_key and m.topology_key != CUBE.topology_key
    np.testing.assert_array_equal(m.vertices, CUBE.vertices)
    assert crease(m, _edge(CUBE, 4, 5), 0.0).creases == {}
    assert crease(m, _edge(CUBE, 0, 1), 10.0).creases == {(0, 1): 10.0, (4, 5): 2.5}
    for bad in ((99, 1.0), (0, -1.0), (0, 11.0)):
        with pytest.raises(OpError):
            crease(CUBE, *bad)
    open_box = PolyMesh.from_faces(CUBE.vertices, CUBE.faces[:5])
    with pytest.raises(OpError, match="boundary"):
        crease(open_box, _edge(open_box, 4, 5), 1.0)


def test_crease_rim_creases_a_face_outline():
    m = crease_rim(CUBE, 5, 10.0)
    assert m.creases == TOP
    assert crease_rim(m, 5, 0.0).creases == {}
    op = CreaseRim(5, 2.0)
    assert genome_mod.from_json([op.to_json()]) == (op,) and op.letter == "R" and "sharpness 2" in op.describe()
    assert op.apply(CUBE).creases == dict.fromkeys(TOP, 2.0)
    open_box = PolyMesh.from_faces(CUBE.vertices, CUBE.faces[:5])
    assert len(crease_rim(open_box, 4, 1.0).creases) == 4  # the bottom: all four edges are interior
    single = PolyMesh.from_faces(CUBE.vertices[:4], [(0, 1, 3, 2)])
    with pytest.raises(OpError, match="no interior edge"):
        crease_rim(single, 0, 1.0)
    with pytest.raises(OpError):
        crease_rim(CUBE, 6, 1.0)
    rng = np.random.default_rng(2)
    drawn = [random_op(rng, CUBE, D, "R") for _ in range(100)]
    assert {o.face for o in drawn} == set(range(6)) and any(o.sharpness == 10.0 for o in drawn)
    assert perturb_op(CreaseRim(1, 1.0), rng, D).face == 1
    chosen = [random_op(rng, CUBE, D, "R", crease_faces=lambda m: [2]).face for _ in range(200)]
    assert 0.7 < chosen.count(2) / 200 < 0.9  # 3/4 proposed, the rest uniform (1/6 of which is face 2 too)


def test_crease_op_json_and_checks():
    op = Crease(3, 10)
    assert op.to_json() == {"op": "crease", "edge": 3, "sharpness": 10.0}
    assert genome_mod.from_json([op.to_json()]) == (op,)
    assert op.letter == "C" and "infinitely sharp" in op.describe() and "1.5" in Crease(3, 1.5).describe()
    for bad in ({"edge": -1, "sharpness": 1}, {"edge": 1, "sharpness": 12}, {"edge": 1, "sharpness": "x"}):
        with pytest.raises(InputError):
            Crease(**bad)
    assert set(ALL_OPS_BY_LETTER) == set(OPS_BY_LETTER) | {"C", "R", "H", "X", "N"}


def test_random_and_perturbed_creases():
    rng = np.random.default_rng(0)
    ranges = OpRanges(sharpness=(0.5, 2.0), infinite=0.3)
    ops = [random_op(rng, CUBE, D, "C", ranges) for _ in range(300)]
    sharp = np.array([op.sharpness for op in ops])
    assert 0.2 < np.mean(sharp == 10.0) < 0.4
    assert np.all((sharp == 10.0) | ((sharp >= 0.5) & (sharp <= 2.0)))
    assert {op.edge for op in ops} == set(range(12))
    proposed = [random_op(rng, CUBE, D, "C", ranges, crease_edges=[3, 5, 99]).edge for _ in range(50)]
    assert set(proposed) == {3, 5}
    assert {random_op(rng, CUBE, D, "C", ranges, crease_edges=lambda m: [m.n_faces]).edge for _ in range(9)} == {6}
    assert random_op(np.random.default_rng(1), CUBE, D, "V", crease_edges=lambda m: 1 / 0).letter == "V"
    assert perturb_op(Crease(2, 10.0), rng, D) == Crease(2, 10.0)
    nudged = [perturb_op(Crease(2, 2.0), rng, D).sharpness for _ in range(50)]
    assert all(0 < s <= 10 for s in nudged) and np.std(nudged) > 0
    with pytest.raises(ConfigError):
        random_op(rng, CUBE, D, "CQ")
    with pytest.raises(ConfigError):
        OpRanges(sharpness=(0.0, 1.0))
    with pytest.raises(ConfigError):
        OpRanges(infinite=1.5)


def test_moves_keep_creases():
    m = CUBE.with_creases(TOP)
    for out in (translate_vertex(m, 4, (0.1, 0, 0)), translate_face(m, 5, 0.2), scale(m, 1.2)):
        assert out.creases == TOP
        assert out.connectivity_key == m.connectivity_key


def test_extrude_copies_the_rim_to_the_cap_inset_does_not():
    m = CUBE.with_creases(TOP)
    e = extrude(m, 5, 0.5)  # new vertices 8..11 above 4, 5, 7, 6
    cap = {tuple(sorted(p)) for p in zip(e.faces[5], e.faces[5][1:] + e.faces[5][:1])}
    assert set(e.creases) == set(TOP) | cap and set(e.creases.values()) == {10.0}
    i = inset(m, 5, 0.1)
    assert i.creases == TOP


def test_edge_loop_keeps_sharpness_on_both_halves():
    m = CUBE.with_creases({(4, 5): 3.0})
    out = edge_loop(m, _edge(m, 4, 5))
    halves = {k: v for k, v in out.creases.items() if 4 in k or 5 in k}
    assert len(halves) == 2 and set(halves.values()) == {3.0}
    (a, b), (c, d) = halves
    assert len({a, b, c, d}) == 3  # the two halves share the cut point


def test_bevel_drops_the_bevelled_edge_and_shortens_its_neighbours():
    m = CUBE.with_creases({(4, 5): 10.0, (5, 7): 2.0, (0, 4): 1.0})
    out = bevel(m, _edge(m, 4, 5), 0.1)
    assert 10.0 not in out.creases.values()
    assert sorted(out.creases.values()) == [1.0, 2.0]
    for (a, b) in out.creases:  # each still an edge, ending at the old far vertex
        assert {a, b} & {0, 7}


def test_subdivision_sees_the_op_creases():
    sharp = crease(CUBE, _edge(CUBE, 4, 5), 10.0)
    a = get_catmull_clark(CUBE, 2).limit(CUBE.vertices).vertices
    b = get_catmull_clark(sharp, 2).limit(sharp.vertices).vertices
    assert np.abs(a - b).max() > 1e-2


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), length=st.integers(1, 10),
       kinds=st.sampled_from(["VELBIFSCR", "CL", "CB", "CEI", "CCVF", "RLB"]))
def test_random_creased_genomes_stay_sound_and_carry_sharpness(seed, length, kinds):
    state, ops = CUBE, []
    for op, state, after in random_history(seed, length, kinds):
        s = after.edge_sharpness  # every crease names an edge of the result
        assert s.shape == (after.topology.n_edges,) and np.all((s >= 0) & (s <= 10))
        assert np.count_nonzero(s) == len(after.creases)
        if isinstance(op, Crease):
            u, v = state.topology.edges[op.edge]
            assert after.creases.get((min(u, v), max(u, v)), 0.0) == op.sharpness
        elif isinstance(op, CreaseRim):
            cyc = state.faces[op.face]
            for u, v in zip(cyc, cyc[1:] + cyc[:1]):
                assert after.creases.get((min(u, v), max(u, v)), 0.0) == op.sharpness
        elif op.letter in "VFS":
            assert after.creases == state.creases
        else:  # E, L, B, I never invent sharpness
            assert set(after.creases.values()) <= set(state.creases.values())
        ops.append(op)
        state = after
    genome = tuple(ops)
    back = genome_mod.from_json(json.loads(json.dumps(genome_mod.to_json(genome))))
    again = genome_mod.replay(CUBE, back)
    assert again.creases == state.creases and again.topology_key == state.topology_key
    get_catmull_clark(state, 1)  # a creased control mesh always subdivides
