"""Curve ops on a control polygon: the paper's add and move, and ``corner`` (a C0 corner by knot multiplicity).

A :class:`Polygon` is the state the ops act on: read-only ``(n, dim)`` control points (dim 2 or 3), the box
``[lo, hi]`` inside which points may be added or moved (the data's bounding box, maybe enlarged), whether
the polygon is closed (a periodic B-spline) and which control points are corners. On an open polygon the
end points lie on the first and last data points and never move or get a neighbour outside them; on a
closed one every point may move. Op parameters are tuples of Python floats, so ops hash and round-trip
exactly through JSON.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from ..errors import ConfigError, InputError, OpError
from ..geometry.bspline import check_corners
from .base import Op, register


def _pair(value, what: str) -> tuple[float, ...]:
    """A finite 2- or 3-tuple of Python floats (x, y[, z]), or InputError."""
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be two or three numbers, got {value!r}") from None
    if len(out) not in (2, 3):
        raise InputError(f"{what} must be two or three numbers, got {value!r}")
    if not all(math.isfinite(v) for v in out):
        raise InputError(f"{what} must be finite, got {value!r}")
    return out


def _index(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise InputError(f"{what} must be an integer, got {value!r}")
    return int(value)


@dataclasses.dataclass(frozen=True, eq=False)
class Polygon:
    """A control polygon ``points`` (read-only ``(n, dim)``), the box ``[lo, hi]`` that bounds edits, whether it is
    ``closed`` (periodic), its ``corners`` (control point indices with knot multiplicity ``degree``) and ``degree``."""

    points: np.ndarray
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    closed: bool = False
    corners: tuple[int, ...] = ()
    degree: int = 3

    def __post_init__(self) -> None:
        pts = np.array(self.points, dtype=np.float64, copy=True) + 0.0  # -0.0 -> 0.0: equal arrays hash alike
        if pts.ndim != 2 or pts.shape[1] not in (2, 3) or len(pts) < 2:
            raise InputError(f"a control polygon needs an (n >= 2, 2 or 3) point array, got shape {pts.shape}")
        if not np.all(np.isfinite(pts)):
            raise InputError("control polygon points must be finite")
        lo, hi = _pair(self.lo, "box corner lo"), _pair(self.hi, "box corner hi")
        if len(lo) != pts.shape[1] or len(hi) != pts.shape[1]:
            raise InputError(f"box corners must have {pts.shape[1]} coordinates like the points")
        if any(a > b for a, b in zip(lo, hi)):
            raise InputError(f"box corner lo {lo} exceeds hi {hi}")
        corners = check_corners(len(pts), self.degree, bool(self.closed), self.corners) if self.corners else ()
        pts.setflags(write=False)
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)
        object.__setattr__(self, "closed", bool(self.closed))
        object.__setattr__(self, "corners", corners)
        object.__setattr__(self, "degree", int(self.degree))

    @property
    def n(self) -> int:
        """Number of control points."""
        return len(self.points)

    @property
    def size(self) -> tuple[float, ...]:
        """Extent of the box along each axis."""
        return tuple(b - a for a, b in zip(self.lo, self.hi))

    def contains(self, xy: tuple[float, ...] | np.ndarray) -> bool:
        """True when ``xy`` lies in the closed box."""
        return bool(all(a <= v <= b for a, v, b in zip(self.lo, xy, self.hi)))

    def with_points(self, points: np.ndarray) -> Polygon:
        """Same box, kind and corners, new control points."""
        return Polygon(points, self.lo, self.hi, self.closed, self.corners, self.degree)

    def _derived(self, points: np.ndarray, corners: tuple[int, ...] | None = None) -> Polygon:
        """Same box, ``points`` a fresh finite float array built by an op (skips validation: ops are hot)."""
        out = object.__new__(Polygon)
        points += 0.0
        points.setflags(write=False)
        object.__setattr__(out, "points", points)
        object.__setattr__(out, "lo", self.lo)
        object.__setattr__(out, "hi", self.hi)
        object.__setattr__(out, "closed", self.closed)
        object.__setattr__(out, "corners", self.corners if corners is None else corners)
        object.__setattr__(out, "degree", self.degree)
        return out

    def __reduce__(self):
        return (Polygon, (self.points, self.lo, self.hi, self.closed, self.corners, self.degree))

    def _key(self) -> tuple:
        return (self.points.shape, self.points.tobytes(), self.lo, self.hi, self.closed, self.corners, self.degree)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Polygon):
            return NotImplemented
        return (self.lo == other.lo and self.hi == other.hi and np.array_equal(self.points, other.points)
                and (self.closed, self.corners, self.degree) == (other.closed, other.corners, other.degree))

    def __hash__(self) -> int:
        return hash(self._key())


def _box(data: np.ndarray, margin: float) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    if not (isinstance(margin, (int, float, np.floating, np.integer)) and math.isfinite(margin) and margin >= 0):
        raise ConfigError(f"box margin must be a finite number >= 0, got {margin!r}")
    lo, hi = data.min(axis=0), data.max(axis=0)
    diag = float(np.linalg.norm(hi - lo))
    if diag == 0.0:
        raise InputError("curve data points all coincide; there is no curve to reconstruct")
    grow = float(margin) * diag
    return tuple((lo - grow).tolist()), tuple((hi + grow).tolist()), diag


def template(points: np.ndarray, margin: float = 0.0, closed: bool = False, degree: int = 3) -> Polygon:
    """The paper's 4-point template for ordered data ``(m, 2)`` (or ``(m, 3)``).

    Open: the first data point, the swapped ``(y, x)`` (3D: rolled) of the first and of the last data point,
    the last data point. Closed: the data points a quarter of the sequence apart. Box: the data's bounding
    box grown by ``margin`` times its diagonal on every side.
    """
    data = np.asarray(points, dtype=np.float64)
    if data.ndim != 2 or data.shape[1] not in (2, 3) or len(data) < 2:
        raise InputError(f"curve data must be an (m >= 2, 2 or 3) array of x, y[, z] rows, got shape {data.shape}")
    if not np.all(np.isfinite(data)):
        raise InputError("curve data must be finite (no NaN or inf)")
    lo, hi, _ = _box(data, margin)
    if closed:
        ctrl = data[(np.arange(4) * len(data)) // 4]
    else:
        first, last = data[0], data[-1]
        ctrl = np.array([first, np.roll(first, 1), np.roll(last, 1), last])
    return Polygon(ctrl, lo, hi, closed=closed, degree=degree)


def template_from_config(config: dict) -> Polygon:
    """The template a curve result's genome replays on, from ``result.config`` (``template``, ``bounds``,
    ``closed``, ``scheme``); InputError when it has none."""
    if "template" not in config:
        raise InputError("the result has no config.template: its modelling history cannot be replayed")
    pts = np.asarray(config["template"], dtype=np.float64)
    big = float(np.finfo(float).max)
    lo, hi = config.get("bounds") or ((-big,) * pts.shape[-1], (big,) * pts.shape[-1])
    degree = 2 if config.get("scheme") == "chaikin" else 3
    return Polygon(pts, tuple(lo), tuple(hi), closed=bool(config.get("closed", False)), degree=degree)


def add_point(polygon: Polygon, index: int, position: tuple[float, ...]) -> Polygon:
    """Insert ``position`` so it becomes ``points[index]``; needs ``1 <= index <= n - 1`` (closed: ``<= n``) and
    a point in the box. Corners after the insertion keep their points."""
    top = polygon.n if polygon.closed else polygon.n - 1
    if not 1 <= index <= top:
        raise OpError(f"add_point index {index} outside [1, {top}]")
    if len(position) != polygon.points.shape[1] or not polygon.contains(position):
        raise OpError(f"add_point position {position} outside the box")
    pts = np.empty((polygon.n + 1, polygon.points.shape[1]))
    pts[:index] = polygon.points[:index]
    pts[index] = position
    pts[index + 1:] = polygon.points[index:]
    return polygon._derived(pts, tuple(c + (c >= index) for c in polygon.corners))


def move_point(polygon: Polygon, index: int, delta: tuple[float, ...]) -> Polygon:
    """Translate ``points[index]`` by ``delta``; open polygons never move their end points; the result must stay
    in the box."""
    lo, hi = (0, polygon.n - 1) if polygon.closed else (1, polygon.n - 2)
    if not lo <= index <= hi:
        raise OpError(f"move_point index {index} outside [{lo}, {hi}]")
    if len(delta) != polygon.points.shape[1]:
        raise OpError(f"move_point delta {delta} has the wrong dimension")
    moved = tuple(a + b for a, b in zip(polygon.points[index].tolist(), delta))
    if not polygon.contains(moved):
        raise OpError(f"move_point would leave the box at {moved}")
    pts = polygon.points.copy()
    pts[index] = moved
    return polygon._derived(pts)


def corner(polygon: Polygon, index: int) -> Polygon:
    """Make ``points[index]`` a C0 corner (interior knot of multiplicity ``degree``: the curve passes through it).

    Needs an index at least ``degree`` from the ends of an open polygon and from every other corner."""
    if index in polygon.corners:
        raise OpError(f"point {index} is already a corner")
    try:
        corners = check_corners(polygon.n, polygon.degree, polygon.closed, polygon.corners + (index,))
    except InputError as exc:
        raise OpError(f"corner {index}: {exc}") from None
    return polygon._derived(polygon.points.copy(), corners)


@register
@dataclasses.dataclass(frozen=True)
class AddPoint(Op):
    """Insert a control point at ``index`` (before the current ``points[index]``)."""

    name: ClassVar[str] = "add_point"
    index: int
    position: tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "index", _index(self.index, "add_point index"))
        object.__setattr__(self, "position", _pair(self.position, "add_point position"))
        object.__setattr__(self, "_hash", hash((1, self.index, self.position)))

    def __hash__(self) -> int:  # cached: genomes of real curves are long and their prefixes are hashed often
        return self._hash

    def apply(self, state: Polygon) -> Polygon:
        return add_point(state, self.index, self.position)


@register
@dataclasses.dataclass(frozen=True)
class MovePoint(Op):
    """Translate the inner control point ``index`` by ``delta``."""

    name: ClassVar[str] = "move_point"
    index: int
    delta: tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "index", _index(self.index, "move_point index"))
        object.__setattr__(self, "delta", _pair(self.delta, "move_point delta"))
        object.__setattr__(self, "_hash", hash((2, self.index, self.delta)))

    def __hash__(self) -> int:
        return self._hash

    def apply(self, state: Polygon) -> Polygon:
        return move_point(state, self.index, self.delta)


@register
@dataclasses.dataclass(frozen=True)
class Corner(Op):
    """Make the control point ``index`` a C0 corner (knot multiplicity = degree)."""

    name: ClassVar[str] = "corner"
    index: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "index", _index(self.index, "corner index"))

    def apply(self, state: Polygon) -> Polygon:
        return corner(state, self.index)


def _floats(xy: np.ndarray) -> tuple[float, ...]:
    return tuple(float(v) for v in xy)


def random_op(rng: np.random.Generator, polygon: Polygon, p_add: float = 0.5, move_scale: float = 1.0,
              local_add: bool = False, corner_sites: np.ndarray | None = None, p_corner: float = 0.0) -> Op:
    """A random curve op for ``polygon``: a corner with probability ``p_corner``, else add with probability
    ``p_add``, else move.

    Corner: at the control point nearest to a random one of ``corner_sites`` (high-curvature data points);
    it may be invalid (repair drops it). Add: index uniform in ``[1, n - 1]``, position uniform in the box
    or, with ``local_add``, Gaussian around the midpoint of the new point's neighbours (sigma a quarter of
    their distance), clipped to the box. Move: index uniform over the movable points, delta uniform in
    ``[-s, s]`` per axis with ``s = move_scale * box size``; the move may leave the box, and is then invalid.
    """
    if not 0.0 <= p_add <= 1.0 or not 0.0 <= p_corner <= 1.0:
        raise ConfigError(f"p_add and p_corner must lie in [0, 1], got {p_add!r}, {p_corner!r}")
    if not (math.isfinite(move_scale) and move_scale >= 0.0):
        raise ConfigError(f"move_scale must be a finite number >= 0, got {move_scale!r}")
    lo, hi = polygon.lo, polygon.hi
    n, dim = polygon.n, len(lo)
    if p_corner > 0.0 and corner_sites is not None and len(corner_sites) and rng.random() < p_corner:
        site = np.asarray(corner_sites)[int(rng.integers(len(corner_sites)))]
        return Corner(int(np.argmin(np.linalg.norm(polygon.points - site, axis=1))))
    if n < 3 or rng.random() < p_add:
        index = int(rng.integers(1, n))
        if local_add:
            a, b = polygon.points[index - 1].tolist(), polygon.points[index].tolist()
            sigma = 0.25 * math.dist(a, b)
            noise = rng.standard_normal(dim).tolist()
            position = tuple(min(max(0.5 * (u + v) + sigma * z, l), h)
                             for u, v, z, l, h in zip(a, b, noise, lo, hi))
        else:  # uniform in the box (scalar arithmetic: array-bound draws cost more than the rest of the op)
            position = tuple(l + (h - l) * r for l, h, r in zip(lo, hi, rng.random(dim).tolist()))
        return AddPoint(index, position)
    index = int(rng.integers(0, n)) if polygon.closed else int(rng.integers(1, n - 1))
    return MovePoint(index, tuple(move_scale * (h - l) * (2.0 * r - 1.0)
                                  for l, h, r in zip(lo, hi, rng.random(dim).tolist())))


def perturb_op(op: Op, rng: np.random.Generator, scale: float) -> Op:
    """The same kind of op on the same index with its position or delta nudged by ``N(0, scale**2)`` per axis
    (a corner has nothing to nudge and comes back unchanged)."""
    if not (math.isfinite(scale) and scale >= 0.0):
        raise ConfigError(f"perturbation scale must be a finite number >= 0, got {scale!r}")
    if isinstance(op, Corner):
        return op
    if isinstance(op, AddPoint):
        return AddPoint(op.index, _floats(np.asarray(op.position) + rng.normal(0.0, scale, len(op.position))))
    if isinstance(op, MovePoint):
        return MovePoint(op.index, _floats(np.asarray(op.delta) + rng.normal(0.0, scale, len(op.delta))))
    raise InputError(f"perturb_op knows only curve ops, got {type(op).__name__}")
