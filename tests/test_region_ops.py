"""The region ops X (extrude a set of faces together) and N (inset a set of faces together)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mesh_ops import random_history, seeded_genomes

from gsr_cad import genome as genome_mod
from gsr_cad.errors import InputError, OpError
from gsr_cad.geometry.polymesh import unit_cube
from gsr_cad.ops.mesh import (EdgeLoop, Extrude, ExtrudeRegion, Inset, InsetRegion, OpRanges, edge_loop,
                              extrude_region, inset_region, perturb_op, random_op)

CUBE = unit_cube()
D = CUBE.diagonal
GRID = edge_loop(edge_loop(CUBE, 0), 1)  # every side of the cube cut once or twice: regions of 2 and 4 faces


def side(mesh, axis: int, sign: float) -> tuple[int, ...]:
    """The faces of ``mesh`` whose unit normal points along ``sign`` times ``axis``."""
    n = mesh.face_normals
    return tuple(int(f) for f in np.flatnonzero(sign * n[:, axis] > 0.9))


TOP = side(GRID, 2, 1.0)
FRONT = side(GRID, 0, 1.0)


def test_the_cube_grid_has_the_regions_the_tests_use():
    assert len(TOP) == 2 and len(FRONT) == 4


def test_extrude_region_moves_the_faces_together_and_copies_the_rim():
    m = extrude_region(inset_region(GRID, TOP, 0.1), TOP, 0.3)
    t = m.topology
    assert t.is_closed and t.is_manifold and t.euler_characteristic == 2
    before = inset_region(GRID, TOP, 0.1)
    rim = 6  # two quads side by side: 6 rim vertices, 6 rim edges, no inner vertex
    assert m.n_vertices == before.n_vertices + rim and m.n_faces == before.n_faces + rim
    for f in TOP:  # the region's faces keep their index, moved by 0.3 up, same shape
        np.testing.assert_allclose(m.vertices[list(m.faces[f])], before.vertices[list(before.faces[f])]
                                   + [0.0, 0.0, 0.3], atol=1e-15)
    np.testing.assert_array_equal(m.vertices[:before.n_vertices], before.vertices)  # the old rim stays
    for u, v, a, b in m.faces[before.n_faces:]:  # each side quad: an old rim edge and its copy above it
        np.testing.assert_allclose(m.vertices[[b, a]] - m.vertices[[u, v]], [[0, 0, 0.3]] * 2, atol=1e-15)


def test_extrude_region_moves_inner_vertices_in_place():
    front = extrude_region(GRID, FRONT, 0.25)  # four quads around one inner vertex
    inner = [c for c in set(GRID.faces[FRONT[0]]) if all(c in GRID.faces[f] for f in FRONT)]
    assert len(inner) == 1
    assert front.n_vertices == GRID.n_vertices + 8 and front.n_faces == GRID.n_faces + 8
    np.testing.assert_allclose(front.vertices[inner[0]], GRID.vertices[inner[0]] + [0.25, 0.0, 0.0])
    assert front.topology.is_closed and front.topology.euler_characteristic == 2


def test_inset_region_keeps_inner_vertices_and_offsets_the_rim():
    m = inset_region(GRID, FRONT, 0.1)
    new = m.vertices[GRID.n_vertices:]
    assert len(new) == 8
    np.testing.assert_allclose(new[:, 0], 0.5)  # in the plane of the flat region
    assert np.abs(new[:, 1:]).max() == pytest.approx(0.4) and np.abs(new[:, 1:]).min() == pytest.approx(0.0)
    np.testing.assert_array_equal(m.vertices[:GRID.n_vertices], GRID.vertices)


@pytest.mark.parametrize("face", range(6))
def test_a_region_of_one_face_is_the_single_face_op(face):
    mesh = inset_region(CUBE, (face,), 0.2)
    for region, single in ((ExtrudeRegion((face,), 0.3), Extrude(face, 0.3)),
                           (ExtrudeRegion((face,), -0.2), Extrude(face, -0.2)),
                           (InsetRegion((face,), 0.15), Inset(face, 0.15))):
        a, b = region.apply(mesh), single.apply(mesh)
        assert a.faces == b.faces
        np.testing.assert_allclose(a.vertices, b.vertices, atol=1e-15)


def test_invalid_regions_are_refused():
    with pytest.raises(OpError, match="whole surface"):
        extrude_region(CUBE, tuple(range(6)), 0.1)
    with pytest.raises(OpError, match="not joined"):
        extrude_region(CUBE, (4, 5), 0.1)  # top and bottom
    with pytest.raises(OpError, match="does not exist"):
        inset_region(CUBE, (0, 99), 0.1)
    with pytest.raises(OpError, match="positive"):
        inset_region(CUBE, (0,), 0.0)
    # two faces touching at one corner only: the region would meet itself there
    corner = [(f, g) for f in range(GRID.n_faces) for g in range(f + 1, GRID.n_faces)
              if len(set(GRID.faces[f]) & set(GRID.faces[g])) == 1]
    assert corner
    with pytest.raises(OpError, match="not joined"):
        extrude_region(GRID, corner[0], 0.1)
    # the eight faces around a face but one corner face: joined by edges, meeting itself at that corner's vertex
    fine = edge_loop(edge_loop(edge_loop(GRID, 2), 3), 0)
    share = [[len(set(f) & set(g)) for g in fine.faces] for f in fine.faces]
    centre = next(f for f in range(fine.n_faces) if sum(1 for x in share[f] if x) == 9)
    ring = [g for g in range(fine.n_faces) if g != centre and share[centre][g]]
    corner = next(g for g in ring if share[centre][g] == 1)
    ring.remove(corner)
    with pytest.raises(OpError, match="meets itself"):
        extrude_region(fine, tuple(ring), 0.1)
    ring.append(corner)  # the whole ring is a region (an annulus: two rims)
    assert extrude_region(fine, tuple(sorted(ring)), 0.1).topology.euler_characteristic == 2


def test_region_op_fields_json_and_description():
    op = ExtrudeRegion([14, 5], 0.3)
    assert op.faces == (5, 14) and op.letter == "X"
    assert op.to_json() == {"op": "extrude_region", "faces": [5, 14], "distance": 0.3}
    assert genome_mod.from_json([op.to_json()]) == (op,)
    n = InsetRegion((5, 14), 0.1)
    assert n.letter == "N" and genome_mod.from_json([n.to_json()]) == (n,) and "[5, 14]" in n.describe()
    for bad in ([], [1, 1], [-1], "12", [1.5]):
        with pytest.raises(InputError):
            ExtrudeRegion(bad, 0.1)
    with pytest.raises(InputError):
        InsetRegion((1,), -0.1)


def test_random_and_perturbed_region_ops():
    rng = np.random.default_rng(3)
    ops = [random_op(rng, GRID, D, "XN", OpRanges(region_faces=3)) for _ in range(200)]
    assert {len(op.faces) for op in ops} == {1, 2, 3}
    applied = 0
    for op in ops:
        try:
            m = op.apply(GRID)
        except OpError:
            continue
        applied += 1
        assert m.topology.is_closed and m.topology.is_manifold and m.topology.euler_characteristic == 2
        p = perturb_op(op, rng, D)
        assert type(p) is type(op) and p.faces == op.faces and p != op
    assert applied > 100


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), length=st.integers(1, 8), kinds=st.sampled_from(["XN", "XNL", "VELXN"]))
def test_random_region_genomes_keep_a_closed_genus_0_mesh(seed, length, kinds):
    for op, before, after in random_history(seed, length, kinds):
        t = after.topology
        assert t.is_closed and t.is_manifold and t.euler_characteristic == 2
        if op.letter in "XN":
            grown = after.n_vertices - before.n_vertices
            assert grown >= 3 and after.n_faces - before.n_faces == grown  # one new vertex and quad per rim edge
            np.testing.assert_array_equal(after.vertices[:before.n_vertices][np.isin(
                np.arange(before.n_vertices), [c for f in op.faces for c in before.faces[f]], invert=True)],
                before.vertices[np.isin(np.arange(before.n_vertices),
                                        [c for f in op.faces for c in before.faces[f]], invert=True)])


def test_an_edge_loop_after_region_ops_still_applies():
    m = genome_mod.replay(CUBE, (EdgeLoop(0), EdgeLoop(1), InsetRegion(TOP, 0.1), ExtrudeRegion(TOP, 0.3),
                                 EdgeLoop(3)))
    assert m.topology.is_closed and m.topology.euler_characteristic == 2


def region_genomes(count: int) -> list[tuple]:
    """``count`` seeded random genomes on the unit cube cut by two loops, over the paper's ops and the region
    ops X and N (regions of up to four faces), each with at least one X and one N on two or more faces."""
    def wide(ops, mesh) -> bool:
        return ({op.letter for op in ops if op.letter in "XN" and len(op.faces) >= 2} == {"X", "N"}
                and mesh.n_faces <= 90)

    return seeded_genomes(count, (EdgeLoop(0), EdgeLoop(1)), "VELBIFSXNXN", 10, wide, first_seed=10_000)
