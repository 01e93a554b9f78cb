"""Curve ops: the paper's template, add/move validity rules (end points fixed, index bounds, box), random ops."""

import json
import pickle

import numpy as np
import pytest

from gsr_cad.errors import ConfigError, InputError, OpError
from gsr_cad.ops.base import REGISTRY, op_from_json
from gsr_cad.ops.curve import AddPoint, MovePoint, Polygon, perturb_op, random_op, template

DATA = np.array([[1.0, 2.0], [3.0, 5.0], [6.0, 4.0], [9.0, 1.0]])


def test_template_follows_the_paper():
    poly = template(DATA)
    np.testing.assert_array_equal(poly.points, [[1, 2], [2, 1], [1, 9], [9, 1]])
    assert poly.n == 4
    assert poly.lo == (1.0, 1.0) and poly.hi == (9.0, 5.0)
    assert all(type(v) is float for v in poly.lo + poly.hi)
    grown = template(DATA, margin=0.5)
    diag = np.hypot(8.0, 4.0)
    np.testing.assert_allclose(grown.lo, (1 - 0.5 * diag, 1 - 0.5 * diag), rtol=1e-15)
    np.testing.assert_allclose(grown.hi, (9 + 0.5 * diag, 5 + 0.5 * diag), rtol=1e-15)


@pytest.mark.parametrize("data,margin,error", [
    (np.zeros((1, 2)), 0.0, InputError),
    (np.zeros((5, 3)), 0.0, InputError),
    (np.array([[0.0, 1.0], [np.nan, 2.0]]), 0.0, InputError),
    (np.ones((6, 2)), 0.0, InputError),
    (DATA, -0.1, ConfigError),
    (DATA, float("inf"), ConfigError),
])
def test_template_rejects_bad_input(data, margin, error):
    with pytest.raises(error):
        template(data, margin)


def test_polygon_is_immutable_hashable_and_compares_by_value():
    poly = template(DATA)
    with pytest.raises(ValueError):
        poly.points[1, 0] = 0.0
    same = Polygon(poly.points.copy(), poly.lo, poly.hi)
    assert same == poly and hash(same) == hash(poly)
    signed = Polygon(np.array([[-0.0, 1.0], [2.0, 3.0]]), (0, 0), (5, 5))
    unsigned = Polygon(np.array([[0.0, 1.0], [2.0, 3.0]]), (0.0, 0.0), (5.0, 5.0))
    assert signed == unsigned and hash(signed) == hash(unsigned)
    assert poly != Polygon(poly.points, poly.lo, (9.0, 6.0))
    with pytest.raises(InputError):
        Polygon(np.zeros((3, 2)), (1.0, 0.0), (0.0, 0.0))
    derived = MovePoint(1, (1.0, 1.0)).apply(poly)  # pickled for process-pool evaluators: stays read-only
    back = pickle.loads(pickle.dumps(derived))
    assert back == derived and not back.points.flags.writeable


def test_add_point_inserts_at_index_within_bounds():
    poly = template(DATA)
    for index in range(1, poly.n):
        out = AddPoint(index, (5.0, 3.0)).apply(poly)
        assert out.n == poly.n + 1
        np.testing.assert_array_equal(out.points[index], (5.0, 3.0))
        np.testing.assert_array_equal(np.delete(out.points, index, axis=0), poly.points)
        assert (out.lo, out.hi) == (poly.lo, poly.hi)
    for index in (0, poly.n, -1):
        with pytest.raises(OpError):
            AddPoint(index, (5.0, 3.0)).apply(poly)
    for outside in ((0.5, 3.0), (5.0, 5.5), (9.0 + 1e-9, 1.0)):
        with pytest.raises(OpError):
            AddPoint(1, outside).apply(poly)
    AddPoint(1, (9.0, 5.0)).apply(poly)  # the box is closed


def test_move_point_keeps_end_points_and_box():
    poly = AddPoint(1, (5.0, 3.0)).apply(template(DATA))
    out = MovePoint(1, (1.0, -1.0)).apply(poly)
    np.testing.assert_array_equal(out.points[1], (6.0, 2.0))
    np.testing.assert_array_equal(np.delete(out.points, 1, axis=0), np.delete(poly.points, 1, axis=0))
    np.testing.assert_array_equal(poly.points[1], (5.0, 3.0))  # the input is untouched
    for index in (0, poly.n - 1, poly.n, -1):
        with pytest.raises(OpError):
            MovePoint(index, (0.0, 0.0)).apply(poly)
    with pytest.raises(OpError):
        MovePoint(1, (0.0, 2.5)).apply(poly)
    with pytest.raises(OpError):  # template points outside the box may only move into it
        MovePoint(3, (0.0, 0.0)).apply(poly)
    assert MovePoint(3, (1.0, -4.0)).apply(poly).points[3].tolist() == [2.0, 5.0]


def test_ops_are_registered_hashable_and_round_trip_through_json():
    assert REGISTRY["add_point"] is AddPoint and REGISTRY["move_point"] is MovePoint
    ops = [AddPoint(2, (0.1, 1 / 3)), MovePoint(1, (-1e-300, 2.5e17))]
    for op in ops:
        text = json.dumps(op.to_json())
        back = op_from_json(json.loads(text))
        assert back == op and hash(back) == hash(op) and type(back) is type(op)
    assert AddPoint(1, (0.0, 0.0)) != MovePoint(1, (0.0, 0.0))
    assert AddPoint(np.int64(2), np.array([1, 2])) == AddPoint(2, (1.0, 2.0))
    assert type(AddPoint(np.int64(2), np.array([1, 2])).position[0]) is float


@pytest.mark.parametrize("data", [
    {"op": "add_point", "index": 1, "position": [float("nan"), 0.0]},
    {"op": "add_point", "index": 1, "position": [1.0]},
    {"op": "move_point", "index": "1", "delta": [0.0, 0.0]},
    {"op": "move_point", "index": 1.5, "delta": [0.0, 0.0]},
    {"op": "move_point", "index": 1},
])
def test_malformed_op_json_raises_input_error(data):
    with pytest.raises(InputError):
        op_from_json(data)


def test_random_op_respects_the_distributions():
    poly = AddPoint(2, (4.0, 4.0)).apply(template(DATA))  # n = 5
    rng = np.random.default_rng(0)
    ops = [random_op(rng, poly, p_add=0.3, move_scale=0.5) for _ in range(3000)]
    adds = [op for op in ops if isinstance(op, AddPoint)]
    moves = [op for op in ops if isinstance(op, MovePoint)]
    assert abs(len(adds) / len(ops) - 0.3) < 0.04
    assert {op.index for op in adds} == set(range(1, poly.n))
    assert {op.index for op in moves} == set(range(1, poly.n - 1))
    assert all(poly.contains(op.position) for op in adds)
    for op in adds:
        op.apply(poly)
    deltas = np.array([op.delta for op in moves])
    s = 0.5 * np.array(poly.size)
    assert np.all(np.abs(deltas) <= s) and np.all(np.abs(deltas).max(axis=0) > 0.95 * s)
    again = np.random.default_rng(0)
    assert ops[:50] == [random_op(again, poly, p_add=0.3, move_scale=0.5) for _ in range(50)]


def test_random_op_local_add_and_edge_cases():
    poly = Polygon(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [10.0, 10.0]]), (-10.0, -10.0), (10.0, 10.0))
    rng = np.random.default_rng(1)
    ops = [random_op(rng, poly, p_add=1.0, local_add=True) for _ in range(2000)]
    assert all(isinstance(op, AddPoint) and poly.contains(op.position) for op in ops)
    first_edge = np.array([op.position for op in ops if op.index == 1])
    np.testing.assert_allclose(first_edge.mean(axis=0), (2.0, 0.0), atol=0.1)
    np.testing.assert_allclose(first_edge.std(axis=0), 1.0, atol=0.1)
    tight = Polygon(poly.points, (0.0, 0.0), (10.0, 10.0))  # half the draws near y = 0 get clipped into it
    assert all(tight.contains(random_op(rng, tight, p_add=1.0, local_add=True).position) for _ in range(200))
    assert all(isinstance(random_op(rng, poly, p_add=0.0), MovePoint) for _ in range(100))
    two = Polygon(np.array([[0.0, 0.0], [1.0, 1.0]]), (0.0, 0.0), (1.0, 1.0))
    assert all(isinstance(random_op(rng, two, p_add=0.0), AddPoint) for _ in range(20))
    with pytest.raises(ConfigError):
        random_op(rng, poly, p_add=1.5)
    with pytest.raises(ConfigError):
        random_op(rng, poly, move_scale=-1.0)


def test_perturb_op_nudges_parameters_only():
    rng = np.random.default_rng(2)
    add, move = AddPoint(3, (1.0, 2.0)), MovePoint(2, (-1.0, 0.5))
    nudged = [perturb_op(add, rng, 0.1) for _ in range(2000)]
    assert all(type(op) is AddPoint and op.index == 3 for op in nudged)
    offsets = np.array([op.position for op in nudged]) - add.position
    np.testing.assert_allclose(offsets.std(axis=0), 0.1, rtol=0.08)
    np.testing.assert_allclose(offsets.mean(axis=0), 0.0, atol=0.01)
    moved = perturb_op(move, rng, 0.1)
    assert type(moved) is MovePoint and moved.index == 2 and moved.delta != move.delta
    assert perturb_op(move, rng, 0.0) == move
    with pytest.raises(ConfigError):
        perturb_op(move, rng, -1.0)
