"""Genome replay, validity, repair and JSON round trip, with hypothesis over random curve genomes."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gsr_cad import genome as G
from gsr_cad.errors import InputError, OpError
from gsr_cad.ops.curve import AddPoint, MovePoint, random_op, template

DATA = np.array([[0.0, 0.0], [2.0, 3.0], [5.0, 4.0], [8.0, 1.0], [10.0, 2.0]])
TEMPLATE = template(DATA)  # box [0, 10] x [0, 4]; the swapped template points (0, 0), (2, 10) partly outside


@st.composite
def genomes(draw, max_ops=14):
    """Genomes that mostly apply (indices and positions drawn for the polygon the prefix builds), with a
    quarter of "wild" ops whose index or parameters may be out of range, so that repair has work to do."""
    n, out = TEMPLATE.n, []
    for _ in range(draw(st.integers(0, max_ops))):
        wild = draw(st.integers(0, 3)) == 0
        if draw(st.booleans()):
            index = draw(st.integers(-1, n + 1) if wild else st.integers(1, n - 1))
            box = ((-2.0, 12.0), (-1.0, 5.0)) if wild else ((0.0, 10.0), (0.0, 4.0))
            out.append(AddPoint(index, (draw(st.floats(*box[0])), draw(st.floats(*box[1])))))
            n += 1
        else:
            index = draw(st.integers(-1, n + 1) if wild else st.integers(1, max(1, n - 2)))
            reach = 8.0 if wild else 1.0
            out.append(MovePoint(index, (draw(st.floats(-reach, reach)), draw(st.floats(-reach, reach)))))
    return tuple(out)


@settings(max_examples=150, deadline=None)
@given(genomes())
def test_repair_output_always_replays_to_the_same_state(genome):
    kept, state = G.repair(TEMPLATE, genome)
    assert G.is_valid(TEMPLATE, kept)
    assert G.replay(TEMPLATE, kept) == state
    assert G.repair(TEMPLATE, kept) == (kept, state)
    assert set(kept) <= set(genome) and len(kept) <= len(genome)
    # The paper's invariants: end points stay on the data's ends; an inner point is in the box unless it
    # is an untouched template point.
    np.testing.assert_array_equal(state.points[[0, -1]], TEMPLATE.points[[0, -1]])
    assert state.n == TEMPLATE.n + sum(isinstance(op, AddPoint) for op in kept)
    for p in state.points[1:-1]:
        assert state.contains(p) or any(np.array_equal(p, q) for q in TEMPLATE.points[1:-1])


@settings(max_examples=100, deadline=None)
@given(genomes())
def test_replay_is_deterministic_and_matches_validity(genome):
    try:
        first = G.replay(TEMPLATE, genome)
    except OpError:
        assert not G.is_valid(TEMPLATE, genome)
        assert G.repair(TEMPLATE, genome)[0] != genome
        return
    assert G.is_valid(TEMPLATE, genome)
    assert G.replay(TEMPLATE, genome) == first
    states = G.replay_states(TEMPLATE, genome)
    assert len(states) == len(genome) + 1 and states[0] is TEMPLATE and states[-1] == first
    assert TEMPLATE.points.tolist() == template(DATA).points.tolist()  # the template is never mutated


@settings(max_examples=100, deadline=None)
@given(genomes())
def test_json_round_trip_is_exact(genome):
    text = json.dumps(G.to_json(genome))
    back = G.from_json(json.loads(text))
    assert back == genome and hash(back) == hash(genome)
    assert G.repair(TEMPLATE, back) == G.repair(TEMPLATE, genome)


def test_random_genomes_from_the_op_factory_mostly_apply():
    rng = np.random.default_rng(0)
    valid = 0
    for _ in range(200):
        state, genome = TEMPLATE, []
        for _ in range(int(rng.integers(4, 9))):
            op = random_op(rng, state)
            try:
                state = op.apply(state)
            except OpError:
                continue
            genome.append(op)
        kept, final = G.repair(TEMPLATE, tuple(genome))
        assert kept == tuple(genome) and final == state
        valid += len(genome)
    assert valid > 200 * 4 * 0.5


def test_dropping_an_add_invalidates_a_later_move_of_its_point():
    genome = (AddPoint(3, (5.0, 2.0)), MovePoint(3, (0.5, 0.5)), AddPoint(1, (1.0, 1.0)))
    state = G.replay(TEMPLATE, genome)
    assert state.n == 6 and state.points[4].tolist() == [5.5, 2.5]
    kept, repaired = G.repair(TEMPLATE, genome[1:])  # without the add, index 3 is the fixed end point
    assert kept == (genome[2],) and repaired.n == 5
    with pytest.raises(OpError):
        G.replay(TEMPLATE, genome[1:])
    assert not G.is_valid(TEMPLATE, genome[1:])


@pytest.mark.parametrize("data", [{"op": "add_point"}, [{"op": "nope"}], [1, 2], [{"index": 1}]])
def test_from_json_rejects_malformed_genomes(data):
    with pytest.raises(InputError):
        G.from_json(data)
