"""The paper's two curve ops on an open control polygon: add a control point, move a control point.

A :class:`Polygon` is the state the ops act on: read-only ``(n, 2)`` control points plus the box
``[lo, hi]`` inside which points may be added or moved (the data's bounding box, maybe enlarged). The
end points lie on the first and last data points and never move or get a neighbour outside them.
Op parameters are tuples of Python floats, so ops hash and round-trip exactly through JSON.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from ..errors import ConfigError, InputError, OpError
from .base import Op, register


def _pair(value, what: str) -> tuple[float, float]:
    """A finite ``(x, y)`` tuple of Python floats, or InputError."""
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be two numbers, got {value!r}") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"{what} must be finite, got {value!r}")
    return (x, y)


def _index(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise InputError(f"{what} must be an integer, got {value!r}")
    return int(value)


@dataclasses.dataclass(frozen=True, eq=False)
class Polygon:
    """An open control polygon ``points`` (read-only ``(n, 2)``) and the box ``[lo, hi]`` that bounds edits."""

    points: np.ndarray
    lo: tuple[float, float]
    hi: tuple[float, float]

    def __post_init__(self) -> None:
        pts = np.array(self.points, dtype=np.float64, copy=True) + 0.0  # -0.0 -> 0.0: equal arrays hash alike
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise InputError(f"a control polygon needs an (n >= 2, 2) point array, got shape {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise InputError("control polygon points must be finite")
        lo, hi = _pair(self.lo, "box corner lo"), _pair(self.hi, "box corner hi")
        if lo[0] > hi[0] or lo[1] > hi[1]:
            raise InputError(f"box corner lo {lo} exceeds hi {hi}")
        pts.setflags(write=False)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    @property
    def n(self) -> int:
        """Number of control points."""
        return len(self.points)

    @property
    def size(self) -> tuple[float, float]:
        """Width and height of the box."""
        return (self.hi[0] - self.lo[0], self.hi[1] - self.lo[1])

    def contains(self, xy: tuple[float, float] | np.ndarray) -> bool:
        """True when ``xy`` lies in the closed box."""
        return bool(self.lo[0] <= xy[0] <= self.hi[0] and self.lo[1] <= xy[1] <= self.hi[1])

    def with_points(self, points: np.ndarray) -> Polygon:
        """Same box, new control points."""
        return Polygon(points, self.lo, self.hi)

    def _derived(self, points: np.ndarray) -> Polygon:
        """Same box, ``points`` a fresh finite float array built by an op (skips validation: ops are hot)."""
        out = object.__new__(Polygon)
        points += 0.0
        points.setflags(write=False)
        object.__setattr__(out, "points", points)
        object.__setattr__(out, "lo", self.lo)
        object.__setattr__(out, "hi", self.hi)
        return out

    def __reduce__(self):
        return (Polygon, (self.points, self.lo, self.hi))

    def _key(self) -> tuple:
        return (self.points.shape, self.points.tobytes(), self.lo, self.hi)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Polygon):
            return NotImplemented
        return self.lo == other.lo and self.hi == other.hi and np.array_equal(self.points, other.points)

    def __hash__(self) -> int:
        return hash(self._key())


def template(points: np.ndarray, margin: float = 0.0) -> Polygon:
    """The paper's 4-point template for ordered data ``(m, 2)``.

    Control points: the first data point, the swapped ``(y, x)`` of the first and of the last data point,
    the last data point. Box: the data's bounding box grown by ``margin`` times its diagonal on every side.
    """
    data = np.asarray(points, dtype=np.float64)
    if data.ndim != 2 or data.shape[1] != 2 or len(data) < 2:
        raise InputError(f"curve data must be an (m >= 2, 2) array of x, y rows, got shape {data.shape}")
    if not np.all(np.isfinite(data)):
        raise InputError("curve data must be finite (no NaN or inf)")
    if not (isinstance(margin, (int, float, np.floating, np.integer)) and math.isfinite(margin) and margin >= 0):
        raise ConfigError(f"box margin must be a finite number >= 0, got {margin!r}")
    lo, hi = data.min(axis=0), data.max(axis=0)
    diag = float(np.hypot(*(hi - lo)))
    if diag == 0.0:
        raise InputError("curve data points all coincide; there is no curve to reconstruct")
    first, last = data[0], data[-1]
    ctrl = np.array([first, first[::-1], last[::-1], last])
    grow = float(margin) * diag
    return Polygon(ctrl, tuple((lo - grow).tolist()), tuple((hi + grow).tolist()))


def add_point(polygon: Polygon, index: int, position: tuple[float, float]) -> Polygon:
    """Insert ``position`` so it becomes ``points[index]``; needs ``1 <= index <= n - 1`` and a point in the box."""
    if not 1 <= index <= polygon.n - 1:
        raise OpError(f"add_point index {index} outside [1, {polygon.n - 1}]")
    if not polygon.contains(position):
        raise OpError(f"add_point position {position} outside the box")
    pts = np.empty((polygon.n + 1, 2))
    pts[:index] = polygon.points[:index]
    pts[index] = position
    pts[index + 1:] = polygon.points[index:]
    return polygon._derived(pts)


def move_point(polygon: Polygon, index: int, delta: tuple[float, float]) -> Polygon:
    """Translate ``points[index]`` by ``delta``; the end points never move and the result must stay in the box."""
    if not 1 <= index <= polygon.n - 2:
        raise OpError(f"move_point index {index} outside [1, {polygon.n - 2}]")
    x, y = polygon.points[index].tolist()
    moved = (x + delta[0], y + delta[1])
    if not polygon.contains(moved):
        raise OpError(f"move_point would leave the box at {moved}")
    pts = polygon.points.copy()
    pts[index] = moved
    return polygon._derived(pts)


@register
@dataclasses.dataclass(frozen=True)
class AddPoint(Op):
    """Insert a control point at ``index`` (before the current ``points[index]``)."""

    name: ClassVar[str] = "add_point"
    index: int
    position: tuple[float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "index", _index(self.index, "add_point index"))
        object.__setattr__(self, "position", _pair(self.position, "add_point position"))

    def apply(self, state: Polygon) -> Polygon:
        return add_point(state, self.index, self.position)


@register
@dataclasses.dataclass(frozen=True)
class MovePoint(Op):
    """Translate the inner control point ``index`` by ``delta``."""

    name: ClassVar[str] = "move_point"
    index: int
    delta: tuple[float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "index", _index(self.index, "move_point index"))
        object.__setattr__(self, "delta", _pair(self.delta, "move_point delta"))

    def apply(self, state: Polygon) -> Polygon:
        return move_point(state, self.index, self.delta)


def _floats(xy: np.ndarray) -> tuple[float, float]:
    return (float(xy[0]), float(xy[1]))


def random_op(rng: np.random.Generator, polygon: Polygon, p_add: float = 0.5, move_scale: float = 1.0,
              local_add: bool = False) -> Op:
    """A random curve op for ``polygon``: add with probability ``p_add``, else move.

    Add: index uniform in ``[1, n - 1]``, position uniform in the box or, with ``local_add``, Gaussian
    around the midpoint of the new point's neighbours (sigma a quarter of their distance), clipped to the
    box. Move: index uniform in ``[1, n - 2]``, delta uniform in ``[-s, s]`` per axis with
    ``s = move_scale * box size``; the move may leave the box, and is then invalid (repair drops it).
    """
    if not 0.0 <= p_add <= 1.0:
        raise ConfigError(f"p_add must lie in [0, 1], got {p_add!r}")
    if not (math.isfinite(move_scale) and move_scale >= 0.0):
        raise ConfigError(f"move_scale must be a finite number >= 0, got {move_scale!r}")
    lo, hi = np.asarray(polygon.lo), np.asarray(polygon.hi)
    n = polygon.n
    if n < 3 or rng.random() < p_add:
        index = int(rng.integers(1, n))
        if local_add:
            a, b = polygon.points[index - 1], polygon.points[index]
            sigma = 0.25 * float(np.hypot(*(b - a)))
            position = np.clip(0.5 * (a + b) + rng.normal(0.0, sigma, 2), lo, hi)
        else:
            position = rng.uniform(lo, hi)
        return AddPoint(index, _floats(position))
    index = int(rng.integers(1, n - 1))
    s = move_scale * (hi - lo)
    return MovePoint(index, _floats(rng.uniform(-s, s)))


def perturb_op(op: Op, rng: np.random.Generator, scale: float) -> Op:
    """The same kind of op on the same index with its position or delta nudged by ``N(0, scale**2)`` per axis."""
    if not (math.isfinite(scale) and scale >= 0.0):
        raise ConfigError(f"perturbation scale must be a finite number >= 0, got {scale!r}")
    nudge = rng.normal(0.0, scale, 2)
    if isinstance(op, AddPoint):
        return AddPoint(op.index, _floats(np.asarray(op.position) + nudge))
    if isinstance(op, MovePoint):
        return MovePoint(op.index, _floats(np.asarray(op.delta) + nudge))
    raise InputError(f"perturb_op knows only curve ops, got {type(op).__name__}")
