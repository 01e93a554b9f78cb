"""Designer-short histories: the moves to a fitted cage are about one per control vertex, ordered so the
intermediate states stay sound rather than staged, and replay exactly."""

from __future__ import annotations

import time

import numpy as np
import pytest

from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import get_catmull_clark, limit_mesh
from gsr_cad.ops.mesh import TranslateVertex, moves_to
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.refine import refine
from gsr_cad.reconstruct.surface import SurfaceProblem, _compact_moves, box_template


def _cube() -> PolyMesh:
    v = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return PolyMesh.from_faces(v, faces)


def _fine_cube() -> PolyMesh:
    cube = _cube()
    return get_catmull_clark(cube, 2, "all").refine(cube.vertices)  # 98 control vertices


def _blob() -> tuple:
    """A randomly scaled once-refined cube's limit surface as a target, and its refinement problem."""
    cube = _cube()
    fine = get_catmull_clark(cube, 1, "all").refine(cube.vertices)
    rng = np.random.default_rng(1)
    truth = fine.with_vertices(fine.vertices * (1.0 + 0.25 * rng.random((fine.n_vertices, 1))))
    target = surface_target(limit_mesh(truth, 3), "blob")
    problem = SurfaceProblem(target, SurfaceConfig(max_target_points=2000), box_template(target))
    problem.max_faces = 400
    return target, problem


@pytest.mark.parametrize("amount, per_vertex", [(1.0, 1.1), (1.5, 1.1)])
def test_moves_that_fold_in_index_order_are_one_per_vertex_and_replay_exactly(amount, per_vertex):
    mesh = _fine_cube()
    v = mesh.vertices
    goal = v + amount * np.c_[np.sin(2.0 * v[:, 2]), np.zeros(len(v)), np.zeros(len(v))]  # a strong shear
    problem = SurfaceProblem(surface_target(limit_mesh(mesh, 1), "cube"), SurfaceConfig(), mesh)
    moving = int(np.sum(np.linalg.norm(goal - v, axis=1) > 1e-12 * problem.diag))
    assert moves_to(mesh, goal, 1e-12 * problem.diag)[2] > 0  # index order alone folds a face
    moves, reached, refused = problem._moves(mesh, goal)
    assert refused == 0 and all(isinstance(op, TranslateVertex) for op in moves)
    assert len(moves) <= per_vertex * moving
    replayed = problem.control_mesh(tuple(moves))
    assert np.abs(replayed.vertices - goal).max() <= 1e-12 * problem.diag
    assert np.array_equal(replayed.vertices, reached.vertices)


def test_a_refined_history_has_about_one_move_per_control_vertex():
    target, problem = _blob()
    genome, levels = refine(problem, (), 5e-4, time.perf_counter() + 120, 400)
    control = problem.control_mesh(genome)
    assert control.n_vertices > 8 and len(levels) >= 2
    moves = sum(isinstance(op, TranslateVertex) for op in genome)
    assert moves <= 1.2 * control.n_vertices
    assert np.abs(control.vertices - levels[-1].control.vertices).max() <= 1e-9 * target.diagonal


def test_staged_moves_merge_within_their_time_and_replay_to_the_same_cage():
    mesh = _fine_cube()
    v = mesh.vertices
    goal = v + 1.5 * np.c_[np.sin(2.0 * v[:, 2]), np.zeros(len(v)), np.zeros(len(v))]
    steps, state = [], mesh
    for k in range(1, 9):  # every vertex in 8 equal stages: 8 moves each
        stage, state, left = moves_to(state, v + (k / 8) * (goal - v), 1e-12)
        assert left == 0
        steps += stage
    merged = _compact_moves(mesh, steps)
    assert len(merged) <= 0.7 * len(steps)  # most vertices keep one move; the ones that would fold, more
    late = _compact_moves(mesh, steps, until=time.perf_counter() - 1.0)  # no time: nothing merged
    assert list(late) == steps
    spent = _compact_moves(mesh, steps, budget=0)  # no replays allowed: nothing merged
    assert list(spent) == steps
    some = _compact_moves(mesh, steps, budget=4 * len(steps))  # a few merges (each replays ~all), deterministic
    assert len(merged) <= len(some) < len(steps) and some == _compact_moves(mesh, steps, budget=4 * len(steps))
    for history in (merged, late, some):
        replayed = mesh
        for op in history:
            replayed = op.apply(replayed)
        assert np.abs(replayed.vertices - goal).max() <= 1e-9


def test_refinement_stops_before_a_history_no_result_can_hold(monkeypatch):
    import gsr_cad.reconstruct.refine as refine_module

    target, problem = _blob()
    free, _ = refine(problem, (), 5e-4, time.perf_counter() + 120, 400)
    limit = len(free) - 1  # one op fewer than the unbounded refinement's history
    monkeypatch.setattr(refine_module, "MAX_OPS", limit)
    genome, levels = refine(problem, (), 5e-4, time.perf_counter() + 120, 400)
    assert len(genome) <= limit
    assert np.abs(problem.control_mesh(genome).vertices - levels[-1].control.vertices).max() <= 1e-9 * target.diagonal


@pytest.mark.parametrize("seed", range(6))
def test_replay_cache_and_run_merge_agree_with_a_plain_replay(seed, monkeypatch):
    """Random histories (structural ops between runs of moves): the prefix-numbered replay cache, with a tiny
    capacity so that entries are evicted mid-walk, keeps exactly the ops a plain replay applies and reaches the
    same cage; the run merge is never longer and replays to the same cage."""
    import gsr_cad.reconstruct.surface as surface_module
    from gsr_cad.errors import OpError
    from gsr_cad.geometry.polymesh import unit_cube
    from gsr_cad.ops.mesh import random_ops

    monkeypatch.setattr(surface_module, "_STATE_CACHE", 7)
    target = surface_target(limit_mesh(unit_cube(), 2))
    problem = SurfaceProblem(target, SurfaceConfig(), box_template(target))
    problem.max_faces = 10**6  # every op that applies is kept, as in the plain replay
    genome, mesh = random_ops(np.random.default_rng(seed), problem.template, 40, "VVVVELI", problem.diag)
    plain, state = [], problem.template
    for op in genome + genome[:5]:  # the tail re-applies early ops, some of which no longer apply
        try:
            state = op.apply(state)
            plain.append(op)
        except OpError:
            pass
    for _ in range(2):  # a cold and a warm cache
        kept, walked = problem.walk(genome + genome[:5])
        assert list(kept) == plain and np.array_equal(walked.vertices, state.vertices)
    merged = problem.merged(genome)
    assert len(merged) <= len(genome)
    np.testing.assert_allclose(problem.control_mesh(merged).vertices, mesh.vertices, atol=1e-12 * problem.diag)


def _turned(v: np.ndarray, degrees: float) -> np.ndarray:
    a = np.radians(degrees)
    rot = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    return v @ rot.T


def test_moves_that_fold_on_the_straight_path_replay_through_the_way_given():
    """A half turn: every straight path between the two cages passes through the axis (every face collapses
    half way), so no staging replays it; through the positions of a 60 and a 120 degree turn (a sound way, as a
    snapped fit's), each leg does, and the moves reach the goal exactly."""
    mesh = _fine_cube()
    problem = SurfaceProblem(surface_target(limit_mesh(mesh, 1), "cube"), SurfaceConfig(), mesh)
    goal = _turned(mesh.vertices, 180.0)
    straight = problem._moves(mesh, goal)
    assert straight[2] > 0
    via = (_turned(mesh.vertices, 60.0), _turned(mesh.vertices, 120.0))
    moves, reached, refused = problem._moves(mesh, goal, via=via)
    assert refused == 0 and all(isinstance(op, TranslateVertex) for op in moves)
    replayed = problem.control_mesh(tuple(moves))
    assert np.abs(replayed.vertices - goal).max() <= 1e-9 * problem.diag
    assert np.array_equal(replayed.vertices, reached.vertices)
    # a way that does not help is not taken: the straight attempt's moves stand
    assert problem._moves(mesh, goal, via=(goal,))[0] == straight[0]
