"""The hole op H: two facing faces removed and their rims bridged (a through-hole, genus + 1)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mesh_ops import random_history

from gsr_cad import genome as genome_mod
from gsr_cad.errors import InputError, OpError
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.geometry.subdivision import get_catmull_clark
from gsr_cad.ops.mesh import Hole, edge_loop, hole, inset, perturb_op, random_op

CUBE = unit_cube()
D = CUBE.diagonal
SLAB = inset(inset(CUBE, 4, 0.2), 5, 0.2)  # inner faces 4 (bottom, on 8..11) and 5 (top, on 12..15)


def genus(mesh) -> int:
    return (2 - mesh.topology.euler_characteristic) // 2


def test_hole_through_the_inset_faces():
    m = hole(SLAB, 4, 5)
    t = m.topology
    assert t.is_closed and t.is_manifold and genus(m) == 1
    assert m.n_vertices == SLAB.n_vertices and m.n_faces == SLAB.n_faces + 2
    # bottom corner 8 (under vertex 0) pairs with top corner 12 (above it): quads 0 and 1 take the faces' slots
    assert m.faces[4] == (8, 9, 15, 12) and m.faces[5] == (9, 10, 14, 15) and m.faces[-2:] == [(10, 11, 13, 14),
                                                                                            (11, 8, 12, 13)]
    np.testing.assert_array_equal(m.vertices, SLAB.vertices)
    limit = get_catmull_clark(m, 2).limit(m.vertices)
    assert np.abs(limit.vertices[:, :2]).max(axis=1).min() > 0.05  # the limit surface leaves the z axis free


def test_two_holes_make_genus_two():
    m = edge_loop(CUBE, CUBE.topology.edges.tolist().index([0, 1]))  # cuts top and bottom in two faces each
    bottom = [f for f in range(m.n_faces) if np.allclose(m.face_normals[f], [0, 0, -1])]
    top = [f for f in range(m.n_faces) if np.allclose(m.face_normals[f], [0, 0, 1])]
    pairs = [(f, min(top, key=lambda g: np.linalg.norm(m.face_centroids[g, :2] - m.face_centroids[f, :2])))
             for f in bottom]
    for f in bottom + top:
        m = inset(m, f, 0.1)  # the inner face keeps the index
    for f, g in pairs:
        m = hole(m, f, g)
    assert len(pairs) == 2 and genus(m) == 2 and m.topology.is_closed and m.topology.is_manifold


@pytest.mark.parametrize("a,b,match", [(4, 4, "differ"), (0, 1, "already joined|face each other"),
                                       (2, 3, "already joined|face each other"), (4, 99, "does not exist"),
                                       (0, 5, "face each other")])
def test_invalid_holes(a, b, match):
    with pytest.raises(OpError, match=match):
        hole(SLAB, a, b)


def test_faces_must_match_and_be_apart():
    with pytest.raises(OpError, match="already joined"):
        hole(CUBE, 4, 5)  # the cube's top and bottom: each bottom corner has an edge to the top one above it
    tri = inset(CUBE, 4, 0.2)
    with pytest.raises(OpError):
        hole(tri, 0, 1)


def test_hole_op_json_random_and_perturb():
    op = Hole(4, 5)
    assert op.to_json() == {"op": "hole", "face_a": 4, "face_b": 5}
    assert genome_mod.from_json([op.to_json()]) == (op,) and op.letter == "H" and "4 and 5" in op.describe()
    with pytest.raises(InputError):
        Hole(-1, 2)
    rng = np.random.default_rng(0)
    assert perturb_op(op, rng, D) == op
    ops = [random_op(rng, SLAB, D, "H") for _ in range(60)]
    assert Hole(4, 5) in ops and Hole(5, 4) in ops
    valid = [o for o in ops if o.face_a != o.face_b]
    for o in valid:
        assert genus(o.apply(SLAB)) == 1 or pytest.fail(str(o))


def test_creases_survive_a_hole():
    m = SLAB.with_creases({(8, 9): 10.0, (12, 13): 2.0})
    assert hole(m, 4, 5).creases == {(8, 9): 10.0, (12, 13): 2.0}


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), length=st.integers(2, 12), kinds=st.sampled_from(["IHC", "IIHL", "VELBIFSCH"]))
def test_random_genomes_with_holes_stay_closed_manifolds(seed, length, kinds):
    holes = 0
    for op, before, after in random_history(seed, length, kinds, sound=False):
        t = after.topology
        assert t.is_closed and t.is_manifold
        holes += op.letter == "H"
        assert t.euler_characteristic == 2 - 2 * holes
        if op.letter == "H":
            assert after.creases == {k: v for k, v in before.creases.items()}
        get_catmull_clark(after, 1)
