"""The operation contract shared by curve and mesh ops.

Every op is a frozen (hence hashable) dataclass wrapping one pure function of the geometry state:
``op.apply(state)`` returns a new state or raises :class:`~gsr_cad.errors.OpError` when the op cannot
apply (an index out of range, a result that would be degenerate). Ops register under a short name so a
genome round-trips through JSON as ``{"op": name, **fields}``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import Any, ClassVar, TypeVar

from ..errors import InputError

REGISTRY: dict[str, type[Op]] = {}

T = TypeVar("T", bound="type[Op]")
S = TypeVar("S")


@dataclasses.dataclass(frozen=True)
class Op:
    """Base of all ops; subclasses set ``name`` and implement ``apply``."""

    name: ClassVar[str] = ""

    def apply(self, state: Any) -> Any:  # pragma: no cover - abstract
        raise NotImplementedError

    def to_json(self) -> dict[str, Any]:
        """JSON form: ``{"op": name, field: value, ...}`` with tuples as lists."""
        out: dict[str, Any] = {"op": self.name}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


def register(cls: T) -> T:
    """Class decorator: make an op constructible from its JSON form."""
    if not cls.name or cls.name in REGISTRY:
        raise ValueError(f"op name {cls.name!r} is empty or taken")
    REGISTRY[cls.name] = cls
    return cls


def op_from_json(data: dict[str, Any]) -> Op:
    """Rebuild an op from its JSON form; unknown names or fields raise InputError."""
    if not isinstance(data, dict) or "op" not in data:
        raise InputError(f"not an op: {data!r}")
    cls = REGISTRY.get(data["op"])
    if cls is None:
        raise InputError(f"unknown op {data['op']!r}")
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            raise InputError(f"op {cls.name!r} lacks field {f.name!r}")
        value = data[f.name]
        kwargs[f.name] = tuple(float(v) for v in value) if isinstance(value, list) else value
    return cls(**kwargs)


def replay(template: S, genome: Iterable[Op]) -> S:
    """Apply every op in order; raises OpError at the first op that cannot apply."""
    state = template
    for op in genome:
        state = op.apply(state)
    return state
