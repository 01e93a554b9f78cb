"""Genomes: tuples of ops replayed in order on a template.

A genome is the modelling history: replaying it on the template rebuilds the control polygon or mesh.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, TypeVar

from .errors import InputError, OpError
from .ops.base import Op, op_from_json, replay

S = TypeVar("S")
Genome = tuple[Op, ...]
__all__ = ["Genome", "from_json", "is_valid", "repair", "replay", "replay_states", "to_json"]


def replay_states(template: S, genome: Iterable[Op]) -> list[S]:
    """The template followed by the state after each op (for history exports and plots)."""
    states = [template]
    for op in genome:
        states.append(op.apply(states[-1]))
    return states


def is_valid(template: Any, genome: Iterable[Op]) -> bool:
    """True when every op applies in order."""
    try:
        replay(template, genome)
    except OpError:
        return False
    return True


def repair(template: S, genome: Iterable[Op]) -> tuple[Genome, S]:
    """Drop the ops that cannot apply (in order) and return the kept genome and its final state."""
    kept: list[Op] = []
    state = template
    for op in genome:
        try:
            state = op.apply(state)
        except OpError:
            continue
        kept.append(op)
    return tuple(kept), state


def to_json(genome: Sequence[Op]) -> list[dict[str, Any]]:
    """The genome as a list of op dicts, in order."""
    return [op.to_json() for op in genome]


def from_json(data: Any) -> Genome:
    """Parse a list of op dicts back into a genome."""
    if not isinstance(data, list):
        raise InputError("genome must be a list of op objects")
    return tuple(op_from_json(d) for d in data)
