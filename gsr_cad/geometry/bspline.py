"""Clamped uniform B-spline curves on the parameter domain [0, 1].

The curve of ``n`` control points and degree ``k`` has ``n - k`` equal spans and end knots of multiplicity
``k + 1``, so it starts on the first and ends on the last control point (the paper's clamped uniform
B-spline). Basis matrices come from :meth:`scipy.interpolate.BSpline.design_matrix`; derivative bases
are the degree-lowered design matrix times the exact difference operator of the control points. Matrices
that depend only on ``(n_ctrl, n_samples, degree)`` are cached and read-only, so evaluating a candidate
control polygon in the GA's hot loop is one small matrix product.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import BSpline

from ..errors import InputError

_PARAM_TOL = 1e-12


def _check_degree(degree: int) -> int:
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 1:
        raise InputError(f"B-spline degree must be an integer >= 1, got {degree!r}")
    return int(degree)


def _check_n_ctrl(n_ctrl: int, degree: int) -> int:
    if isinstance(n_ctrl, bool) or not isinstance(n_ctrl, (int, np.integer)) or n_ctrl < degree + 1:
        raise InputError(f"a degree-{degree} B-spline needs at least {degree + 1} control points, got {n_ctrl!r}")
    return int(n_ctrl)


def _check_params(params: np.ndarray) -> np.ndarray:
    """Parameters as a finite 1-D float array in [0, 1] (round-off just outside is clipped)."""
    x = np.asarray(params, dtype=np.float64)
    if x.ndim != 1:
        x = x.reshape(-1)
    if not np.all(np.isfinite(x)):
        raise InputError("curve parameters must be finite")
    if x.size and (x.min() < -_PARAM_TOL or x.max() > 1.0 + _PARAM_TOL):
        raise InputError("curve parameters must lie in [0, 1]")
    return np.clip(x, 0.0, 1.0)


def _check_ctrl(ctrl: np.ndarray, degree: int) -> np.ndarray:
    c = np.asarray(ctrl, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] < 1:
        raise InputError(f"control points must be an (n, dim) array, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise InputError("control points must be finite")
    _check_n_ctrl(len(c), degree)
    return c


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@functools.lru_cache(maxsize=256)
def _knots(n_ctrl: int, degree: int) -> np.ndarray:
    n_spans = n_ctrl - degree
    inner = np.arange(1, n_spans, dtype=np.float64) / n_spans
    return _readonly(np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)]))


def clamped_uniform_knots(n_ctrl: int, degree: int = 3) -> np.ndarray:
    """Knot vector on [0, 1] with ``n_ctrl - degree`` equal spans and multiplicity ``degree + 1`` at the ends."""
    degree = _check_degree(degree)
    return _knots(_check_n_ctrl(n_ctrl, degree), degree).copy()


def _design(n_ctrl: int, x: np.ndarray, degree: int) -> sp.csr_array:
    """Sparse ``(m, n_ctrl)`` basis at checked parameters ``x``."""
    return BSpline.design_matrix(x, _knots(n_ctrl, degree), degree)


@functools.lru_cache(maxsize=256)
def _difference_operator(n_ctrl: int, degree: int, order: int) -> sp.csr_array:
    """Map control points to the control points of the ``order``-th derivative curve.

    One step: ``Q_i = k (P_{i+1} - P_i) / (t_{i+k+1} - t_{i+1})``; the derivative is again a clamped
    uniform B-spline of degree ``k - 1`` on the knots ``t[1:-1]``.
    """
    op = sp.identity(n_ctrl, format="csr")
    t, k, n = _knots(n_ctrl, degree), degree, n_ctrl
    for _ in range(order):
        scale = k / (t[k + 1:n + k] - t[1:n])
        step = sp.diags_array([-scale, scale], offsets=[0, 1], shape=(n - 1, n), format="csr")
        op = step @ op
        t, k, n = t[1:-1], k - 1, n - 1
    return sp.csr_array(op)


def basis_matrix(n_ctrl: int, params: np.ndarray, degree: int = 3) -> np.ndarray:
    """Dense ``(m, n_ctrl)`` matrix of the B-spline basis functions at ``params`` (curve = matrix @ ctrl)."""
    degree = _check_degree(degree)
    n_ctrl = _check_n_ctrl(n_ctrl, degree)
    return _design(n_ctrl, _check_params(params), degree).toarray()


@functools.lru_cache(maxsize=256)
def _uniform_basis(n_ctrl: int, n_samples: int, degree: int) -> np.ndarray:
    return _readonly(_design(n_ctrl, np.linspace(0.0, 1.0, n_samples), degree).toarray())


def uniform_basis(n_ctrl: int, n_samples: int, degree: int = 3) -> np.ndarray:
    """Read-only cached basis at ``linspace(0, 1, n_samples)``: the fitness's sampling matrix."""
    degree = _check_degree(degree)
    n_ctrl = _check_n_ctrl(n_ctrl, degree)
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or n_samples < 2:
        raise InputError(f"need at least 2 curve samples, got {n_samples!r}")
    return _uniform_basis(n_ctrl, int(n_samples), degree)


def derivative_basis_matrix(n_ctrl: int, params: np.ndarray, degree: int = 3, order: int = 1) -> np.ndarray:
    """Dense ``(m, n_ctrl)`` matrix of the ``order``-th parameter derivatives of the basis functions."""
    degree = _check_degree(degree)
    n_ctrl = _check_n_ctrl(n_ctrl, degree)
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
        raise InputError(f"derivative order must be an integer >= 0, got {order!r}")
    x = _check_params(params)
    if order > degree:
        return np.zeros((x.size, n_ctrl))
    if order == 0:
        return _design(n_ctrl, x, degree).toarray()
    lowered = BSpline.design_matrix(x, _knots(n_ctrl, degree)[order:-order], degree - order)
    return (lowered @ _difference_operator(n_ctrl, degree, int(order))).toarray()


def evaluate(ctrl: np.ndarray, params: np.ndarray, degree: int = 3) -> np.ndarray:
    """Points ``(m, dim)`` of the curve at ``params`` in [0, 1]."""
    degree = _check_degree(degree)
    c = _check_ctrl(ctrl, degree)
    return np.asarray(_design(len(c), _check_params(params), degree) @ c)


def sample_uniform(ctrl: np.ndarray, n_samples: int, degree: int = 3) -> np.ndarray:
    """``n_samples`` curve points at evenly spaced parameters (cached basis: one matrix product)."""
    degree = _check_degree(degree)
    c = _check_ctrl(ctrl, degree)
    return uniform_basis(len(c), n_samples, degree) @ c


def _insert_knot(t: np.ndarray, coef: np.ndarray, u: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Boehm's knot insertion of ``u`` (once) into a degree-``k`` spline with coefficient rows ``coef``."""
    s = int(np.searchsorted(t, u, side="right")) - 1
    i = np.arange(s - k + 1, s + 1)
    alpha = ((u - t[i]) / (t[i + k] - t[i]))[:, None]
    blended = (1.0 - alpha) * coef[i - 1] + alpha * coef[i]
    new = np.concatenate([coef[: s - k + 1], blended, coef[s:]])
    return np.insert(t, s + 1, u), new


@functools.lru_cache(maxsize=128)
def _bezier_extraction(n_ctrl: int, degree: int) -> np.ndarray:
    """``(n_spans * (degree + 1), n_ctrl)`` matrix giving every span's Bezier points from the control points."""
    t, coef, k = _knots(n_ctrl, degree), np.eye(n_ctrl), degree
    for u in _knots(n_ctrl, degree)[k + 1:n_ctrl]:
        for _ in range(k - 1):
            t, coef = _insert_knot(t, coef, float(u), k)
    n_spans = n_ctrl - k
    rows = (np.arange(n_spans)[:, None] * k + np.arange(k + 1)[None, :]).ravel()
    return _readonly(coef[rows])


def bezier_segments(ctrl: np.ndarray, degree: int = 3) -> np.ndarray:
    """The exact Bezier pieces ``(n_spans, degree + 1, dim)`` of the curve, span ``j`` on ``[j, j + 1] / n_spans``.

    Obtained by inserting every interior knot until its multiplicity is ``degree``; used by SVG/DXF export.
    """
    degree = _check_degree(degree)
    c = _check_ctrl(ctrl, degree)
    n_spans = len(c) - degree
    return (_bezier_extraction(len(c), degree) @ c).reshape(n_spans, degree + 1, c.shape[1])


# --- closed (periodic) curves and corners ------------------------------------------------------------------------
#
# A curve of ``n`` control points is either clamped (open) or periodic (closed: the polygon wraps). A *corner*
# at control point ``i`` merges the knots ``t[i+1] .. t[i+k]`` into one knot of multiplicity ``k`` (the degree):
# the curve passes through ``P_i`` there and is only C0. Distinct knot values stay evenly spaced.


def check_corners(n_ctrl: int, degree: int, closed: bool, corners) -> tuple[int, ...]:
    """Sorted corner indices, or InputError when one is out of range or two share knots (closer than ``degree``)."""
    degree = _check_degree(degree)
    n_ctrl = _check_n_ctrl(n_ctrl, degree)
    try:
        out = tuple(sorted({int(i) for i in corners}))
    except (TypeError, ValueError):
        raise InputError(f"corners must be control point indices, got {corners!r}") from None
    if not out:
        return out
    lo, hi = (0, n_ctrl - 1) if closed else (degree, n_ctrl - 1 - degree)
    if out[0] < lo or out[-1] > hi:
        raise InputError(f"corner indices must lie in [{lo}, {hi}] for {n_ctrl} control points, got {list(out)}")
    gaps = np.diff(np.array(out + ((out[0] + n_ctrl,) if closed else ())))
    if gaps.size and gaps.min() < degree:
        raise InputError(f"corners must be at least {degree} control points apart, got {list(out)}")
    return out


@functools.lru_cache(maxsize=512)
def _form_knots(n_ctrl: int, degree: int, closed: bool, corners: tuple[int, ...]) -> np.ndarray:
    k, n = degree, n_ctrl
    merged = {j for i in corners for j in range(i + 2, i + k + 1)}  # knot indices equal to their predecessor
    if not closed:
        slots = np.arange(k + 1, n)
        new = np.array([j not in merged for j in slots], dtype=bool)
        group = np.cumsum(new)
        inner = group / (group[-1] + 1) if slots.size else np.zeros(0)
        return _readonly(np.concatenate([np.zeros(k + 1), inner, np.ones(k + 1)]))
    return _readonly(_periodic_knots(n, k, merged, n + 2 * k + 1))


def _periodic_knots(n: int, k: int, merged: set[int], length: int) -> np.ndarray:
    """``length`` knots ``t[0..]`` of a periodic form (period 1, ``t[k] = 0``); ``merged``: indices equal to
    their predecessor (taken modulo ``n``)."""
    merged_mod = {m % n for m in merged}
    new = np.array([(j % n) not in merged_mod for j in range(k, k + n)], dtype=bool)
    if not new.any():
        raise InputError("a closed curve needs at least one simple knot")
    starts = np.cumsum(new)  # leading merged indices continue the group that closes the previous period
    period = (starts - starts[0]) / int(starts[-1])
    j = np.arange(length)
    return period[(j - k) % n] + np.floor_divide(j - k, n)


def form_knots(n_ctrl: int, degree: int = 3, closed: bool = False, corners=()) -> np.ndarray:
    """Knot vector of a curve form: clamped on [0, 1] (``n + k + 1`` knots) or periodic with period 1
    (``n + 2k + 1`` knots for the ``n + k`` wrapped coefficients); corners repeat interior knots ``k`` times."""
    corners = check_corners(n_ctrl, degree, closed, corners)
    return _form_knots(int(n_ctrl), int(degree), bool(closed), corners).copy()


def wrapped(ctrl: np.ndarray, degree: int, closed: bool) -> np.ndarray:
    """B-spline coefficients of a form: the control points, followed by the first ``degree`` again when closed."""
    c = np.asarray(ctrl, dtype=np.float64)
    return np.concatenate([c, c[:degree]]) if closed else c


def make_spline(ctrl: np.ndarray, degree: int = 3, closed: bool = False, corners=()) -> BSpline:
    """SciPy ``BSpline`` of a curve form on the parameter domain [0, 1] (periodic extrapolation when closed)."""
    degree = _check_degree(degree)
    c = _check_ctrl(ctrl, degree)
    t = _form_knots(len(c), degree, bool(closed), check_corners(len(c), degree, closed, corners))
    return BSpline(t, wrapped(c, degree, closed), degree, extrapolate="periodic" if closed else True)


def form_design(n_ctrl: int, params: np.ndarray, degree: int = 3, closed: bool = False, corners=()) -> sp.csr_array:
    """Sparse ``(m, n_ctrl)`` basis of a curve form at ``params`` (closed: parameters taken modulo 1)."""
    degree = _check_degree(degree)
    n_ctrl = _check_n_ctrl(n_ctrl, degree)
    corners = check_corners(n_ctrl, degree, closed, corners)
    t = _form_knots(n_ctrl, degree, bool(closed), corners)
    x = np.asarray(params, dtype=np.float64).reshape(-1)
    if not closed:
        return BSpline.design_matrix(_check_params(x), t, degree)
    full = BSpline.design_matrix(np.mod(x, 1.0), t, degree).tocoo()
    return sp.csr_array((full.data, (full.row, full.col % n_ctrl)), shape=(x.size, n_ctrl))


def clamped_form(control_points: np.ndarray, degree: int = 3, closed: bool = False,
                 corners=()) -> tuple[np.ndarray, np.ndarray]:
    """An exact clamped (end-interpolating) representation ``(knots, poles)`` of any curve form on [0, 1].

    Open curves keep their poles; corners appear as interior knots of multiplicity ``degree``. A closed
    (periodic) curve is cut at parameter 0 by Boehm knot insertion until the knot there has multiplicity
    ``degree``; its poles then start and end on the curve point at 0 (the same point), and the knot vector
    gets end multiplicity ``degree + 1``. Evaluating ``BSpline(knots, poles, degree)`` on [0, 1] gives the
    same curve as :func:`make_spline` up to round-off.
    """
    degree = _check_degree(degree)
    c = _check_ctrl(control_points, degree)
    corners = check_corners(len(c), degree, closed, corners)
    t = _form_knots(len(c), degree, bool(closed), corners)
    if not closed:
        return t.copy(), c.copy()
    k, n = degree, len(c)
    merged = {j for i in corners for j in range(i + 2, i + k + 1)}
    t = _periodic_knots(n, k, merged, n + 3 * k + 1)  # one spare period end, so insertion at 1 has neighbours
    coef = c[np.arange(n + 2 * k) % n]
    for u in (0.0, 1.0):
        while np.count_nonzero(np.abs(t - u) <= 1e-14) < k:
            t, coef = _insert_knot(t, coef, u, k)
        t[np.abs(t - u) <= 1e-14] = u
    first = int(np.flatnonzero(t == 0.0)[0])
    inner = t[(t > 0.0) & (t < 1.0)]
    knots = np.concatenate([np.zeros(k + 1), inner, np.ones(k + 1)])
    poles = coef[first - 1:first - 1 + len(knots) - k - 1]
    return knots, poles


def bezier_pieces(knots: np.ndarray, poles: np.ndarray, degree: int = 3) -> np.ndarray:
    """The exact Bezier pieces ``(n_pieces, degree + 1, dim)`` of a clamped B-spline with any knot vector (one
    piece per non-empty knot span, in order), by inserting every interior knot up to multiplicity ``degree``."""
    k = _check_degree(degree)
    t, coef = np.asarray(knots, dtype=np.float64).copy(), np.asarray(poles, dtype=np.float64).copy()
    for u in np.unique(t[k + 1:len(t) - k - 1]):
        while np.count_nonzero(t == u) < k:
            t, coef = _insert_knot(t, coef, float(u), k)
    n_pieces = (len(coef) - 1) // k
    rows = (np.arange(n_pieces)[:, None] * k + np.arange(k + 1)[None, :]).ravel()
    return coef[rows].reshape(n_pieces, k + 1, coef.shape[1])
