"""Mesh isomorphisms and the history rewrite: renumbered copies are recognised, non-isomorphic meshes are
not, and a search history (two edge loops and moves) is rewritten into the designer's (inset, extrude)
that builds the same control mesh."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gsr_cad.errors import OpError
from gsr_cad.genome import replay
from gsr_cad.geometry.isomorphism import connectivity_hash, isomorphisms
from gsr_cad.geometry.polymesh import PolyMesh, unit_cube
from gsr_cad.ops.mesh import EdgeLoop, Extrude, TranslateVertex, moves_to, random_op, random_ops
from gsr_cad.ops.rewrite import simplify_history, skeletons
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES


def renumbered(mesh: PolyMesh, rng: np.random.Generator) -> tuple[PolyMesh, np.ndarray]:
    """A copy with vertices, faces and each face's first corner shuffled; and old -> new vertex index."""
    perm = rng.permutation(mesh.n_vertices)
    vertices = np.empty_like(mesh.vertices)
    vertices[perm] = mesh.vertices
    faces = []
    for f in rng.permutation(mesh.n_faces):
        cyc = [int(perm[v]) for v in mesh.faces[f]]
        k = int(rng.integers(len(cyc)))
        faces.append(cyc[k:] + cyc[:k])
    return PolyMesh.from_faces(vertices, faces), perm


def random_mesh(seed: int, n_ops: int) -> PolyMesh:
    rng = np.random.default_rng(seed)
    mesh = unit_cube()
    applied = 0
    for _ in range(20 * n_ops):
        if applied == n_ops:
            break
        try:
            mesh = random_op(rng, mesh, mesh.diagonal, "ELBI").apply(mesh)
            applied += 1
        except OpError:
            continue
    assert applied == n_ops, f"applied {applied} of {n_ops} ops (seed {seed})"
    return mesh


def test_the_cube_has_24_rotations():
    cube = unit_cube()
    phis = list(isomorphisms(cube, cube, limit=100))
    assert len(phis) == 24
    assert len({tuple(p) for p in phis}) == 24
    for phi in phis:  # each is a rotation: it keeps every edge length and the volume's orientation
        faces = {tuple(sorted(f)) for f in cube.faces}
        assert {tuple(sorted(int(phi[v]) for v in f)) for f in cube.faces} == faces


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.integers(0, 4))
def test_a_renumbered_copy_is_found_and_the_map_carries_faces_to_faces(seed, n_ops):
    mesh = random_mesh(seed, n_ops)
    copy, perm = renumbered(mesh, np.random.default_rng(seed + 1))
    assert connectivity_hash(copy) == connectivity_hash(mesh)
    phis = list(isomorphisms(mesh, copy))
    assert phis
    cycles = {tuple(f[i:] + f[:i]) for f in copy.faces for i in range(len(f))}
    for phi in phis:
        assert all(tuple(int(phi[v]) for v in f) in cycles for f in mesh.faces)
    # the geometry says which one is the renumbering
    assert any(np.array_equal(phi, perm) for phi in phis)


def test_different_connectivity_has_no_isomorphism():
    cube = unit_cube()
    extruded = Extrude(1, 0.5).apply(cube)
    looped = EdgeLoop(0).apply(cube)
    assert list(isomorphisms(cube, extruded)) == []
    # same counts (12 vertices, 10 faces) and the same connectivity: an extrusion is a loop
    assert list(isomorphisms(extruded, looped))


def _loops_and_moves(goal: PolyMesh, template: PolyMesh) -> tuple:
    """Two edge loops, then one move per vertex that is not in place: the search's history of ``goal``."""
    for e1 in range(12):
        for e2 in range(20):
            try:
                mesh = replay(template, (EdgeLoop(e1), EdgeLoop(e2)))
            except OpError:
                continue
            phi = next(isomorphisms(mesh, goal), None)
            if phi is None:
                continue
            delta = goal.vertices[phi] - mesh.vertices
            moves = tuple(TranslateVertex(i, tuple(d)) for i, d in enumerate(delta) if np.any(d != 0))
            return (EdgeLoop(e1), EdgeLoop(e2)) + moves
    raise AssertionError("no two loops build the goal's connectivity")


def test_two_loops_and_moves_become_inset_then_extrude():
    sample = SURFACE_SAMPLES["inset_extrude"]()
    goal, cube = sample.truth_control, unit_cube()
    searched = _loops_and_moves(goal, cube)
    assert "".join(op.letter for op in searched).startswith("LLV")
    rewritten = simplify_history(cube, searched)
    assert rewritten == sample.truth_genome  # the parameters come out exact: inset 0.2, extrude 0.5
    built = replay(cube, rewritten)
    phi = next(isomorphisms(built, goal))
    np.testing.assert_allclose(built.vertices, goal.vertices[phi], atol=1e-12)


def test_on_a_stretched_template_the_corners_move_first():
    sample = SURFACE_SAMPLES["inset_extrude"]()
    cube = unit_cube()
    template = cube.with_vertices(cube.vertices * np.array([1.1, 0.9, 1.6]))
    goal = sample.truth_control
    searched = _loops_and_moves(goal, template)
    rewritten = simplify_history(template, searched)
    assert "".join(op.letter for op in rewritten) == "V" * 8 + "IE"
    built = replay(template, rewritten)
    assert any(np.abs(built.vertices - goal.vertices[phi]).max() <= 1e-12 for phi in isomorphisms(built, goal))


def test_tolerance_lets_a_nearly_exact_mesh_take_the_short_history():
    sample = SURFACE_SAMPLES["inset_extrude"]()
    cube = unit_cube()
    noise = np.random.default_rng(3).normal(0.0, 1e-9, sample.truth_control.vertices.shape)
    goal = sample.truth_control.with_vertices(sample.truth_control.vertices + noise)
    searched = _loops_and_moves(goal, cube)
    exact = simplify_history(cube, searched)
    assert sum(op.letter == "V" for op in exact) >= 8  # exactly: the noise needs its moves
    loose = simplify_history(cube, searched, tolerance=1e-6)
    assert [op.letter for op in loose] == ["I", "E"]
    built = replay(cube, loose)
    gap = min(np.abs(built.vertices - goal.vertices[phi]).max() for phi in isomorphisms(built, goal))
    assert gap <= 1e-6 * goal.diagonal


def test_a_short_history_is_kept_and_structural_ops_beyond_the_limit_are_left_alone():
    cube = unit_cube()
    assert simplify_history(cube, (Extrude(1, 1.0),)) == (Extrude(1, 1.0),)
    long = (EdgeLoop(0), EdgeLoop(0), EdgeLoop(0), EdgeLoop(0), TranslateVertex(0, (0.1, 0.0, 0.0)))
    assert simplify_history(cube, long, max_ops=3) == long
    assert simplify_history(cube, (TranslateVertex(0, (0.1, 0.0, 0.0)),)) == (TranslateVertex(0, (0.1, 0.0, 0.0)),)


def test_skeletons_respect_the_allowed_kinds():
    goal = SURFACE_SAMPLES["inset_extrude"]().truth_control
    letters = {"".join(op.letter for op in s) for s in skeletons(unit_cube(), goal, "EL", 2)}
    assert letters == {"EE", "EL", "LE", "LL"}


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000))
def test_a_rewrite_is_never_longer_and_builds_the_same_mesh(seed):
    cube = unit_cube()
    genome, mesh = random_ops(np.random.default_rng(seed), cube, 5, "VEILF")
    genome = list(genome)
    out = simplify_history(cube, genome, budget=3000)
    assert len(out) <= len(genome)
    built = replay(cube, out)
    gap = min(np.abs(built.vertices - mesh.vertices[phi]).max() for phi in isomorphisms(built, mesh))
    assert gap <= 1e-12 * mesh.diagonal


def test_moves_to_takes_a_mesh_to_new_positions_or_says_how_many_it_could_not():
    cube = unit_cube()
    goal = cube.vertices * np.array([1.5, 1.0, 0.5]) + 0.1
    moves, moved, refused = moves_to(cube, goal, 1e-12)
    assert refused == 0 and len(moves) == 8 and all(isinstance(op, TranslateVertex) for op in moves)
    np.testing.assert_allclose(moved.vertices, goal, atol=1e-15)
    assert moves_to(cube, cube.vertices, 1e-12)[0] == ()
    # a vertex pushed through the opposite face would fold its faces: that move is refused
    folded = cube.vertices.copy()
    folded[0] = -cube.vertices[0] * 3.0
    moves, moved, refused = moves_to(cube, folded, 1e-12)
    assert refused == 1 and moves == () and moved is cube
