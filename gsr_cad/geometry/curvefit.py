"""Least-squares placement of a curve's control points (the polish the paper lacks).

Curve points are linear in the control points, so for a fixed count and fixed parameters the best
control points solve a linear least-squares problem: on an open curve the end points stay on the first and
last data points (the paper's clamped template) and the interior is solved; on a closed (periodic) curve
every control point is free. With ``parametrization="geometric"`` the parameters are refined by foot-point
projection (alternating with the solve), which removes the paper's assumption that the data are evenly
spaced in parameter; the better of a uniform and a chord-length start (after one solve) is refined, and
:func:`tangent_refine` (Gauss-Newton with the parameters eliminated) finishes what alternating correction
leaves (optionally with the open curve's end points free, for noisy ends). :func:`warped_fit` is the
index-wise correspondence with a smooth warp of the evenly spaced parameters (variable projection). Large
systems (many control points) are solved through their sparse banded normal equations.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Literal

import numpy as np
import scipy.sparse as sp
import scipy.linalg as sla
from scipy.interpolate import BSpline
from scipy.optimize import least_squares, lsq_linear
from scipy.sparse.linalg import splu

from . import bspline
from .distance import chord_length_params, spline_foot_points

_DENSE_COLUMNS = 64  # up to this many unknowns the normal matrix is factored densely
_JOINT_POINTS = 120  # joint refinement only for at most this many points (dense Jacobian; sparse data)
_JOINT_RMS = 2e-3  # ... and near-exact data (RMS below this fraction of the diagonal): noisy fits gain nothing
_FINER = (1, 2, 4, 8)  # extra control points of the fits whose parameters restart a joint step (sparse data)
_EXACT = 1e-12  # an RMS below this fraction of the diagonal is exact: no further starts


@dataclasses.dataclass(frozen=True)
class CurveFit:
    """A fitted control polygon and how well it fits (distances are absolute, per data point)."""

    ctrl: np.ndarray
    params: np.ndarray
    distances: np.ndarray
    closed: bool = False

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.distances ** 2)))


def _rows(n_ctrl: int, params: np.ndarray, degree: int, closed: bool) -> tuple[np.ndarray, np.ndarray]:
    """The basis as ``(columns, values)``, both ``(m, degree + 1)``: each row's nonzero basis functions (closed:
    columns taken modulo ``n_ctrl``). Straight from SciPy's design matrix, which stores ``degree + 1`` per row."""
    t = bspline._form_knots(n_ctrl, degree, bool(closed), ())
    x = np.mod(params, 1.0) if closed else bspline._check_params(params)
    design = BSpline.design_matrix(x, t, degree)
    cols = design.indices.reshape(-1, degree + 1).astype(np.int64)
    vals = np.asarray(design.data, dtype=np.float64).reshape(-1, degree + 1)
    return (cols % n_ctrl if closed else cols), vals


def _normal(cols: np.ndarray, vals: np.ndarray, rhs: np.ndarray, n: int, dense: bool
            ) -> tuple[np.ndarray, np.ndarray]:
    """Normal matrix and right-hand side of a basis given row-wise: the matrix dense ``(n, n)``, or as its band
    ``(2 degree + 1, n)`` with ``band[degree + d, i] = N[i, (i + d) mod n]``."""
    k1 = cols.shape[1]
    k = k1 - 1
    atb = _transpose_product(cols, vals, rhs, n)
    ca = np.repeat(cols, k1, axis=1).ravel()
    cb = np.tile(cols, (1, k1)).ravel()
    w = (vals[:, :, None] * vals[:, None, :]).ravel()
    if dense:
        return np.bincount(ca * n + cb, w, n * n).reshape(n, n), atb
    d = np.mod(cb - ca + k, n)  # n > 2 k + 1 here: offsets -k..k do not alias
    return np.bincount(d * n + ca, w, (2 * k + 1) * n).reshape(2 * k + 1, n), atb


def _transpose_product(cols: np.ndarray, vals: np.ndarray, rhs: np.ndarray, n: int) -> np.ndarray:
    """``A.T @ rhs`` for a basis ``A`` given row-wise."""
    return np.column_stack([np.bincount(cols.ravel(), (vals * rhs[:, d:d + 1]).ravel(), n)
                            for d in range(rhs.shape[1])])


def _band_solver(band: np.ndarray, lo: int, hi: int, closed: bool) -> Callable[[np.ndarray], np.ndarray]:
    """A solver for the unknowns ``lo..hi-1`` of a banded normal matrix (closed: cyclic band, sparse LU; open:
    banded Cholesky)."""
    k = band.shape[0] // 2
    n = band.shape[1]
    if not closed:
        upper = np.zeros((k + 1, hi - lo))
        for d in range(k + 1):  # solveh_banded's upper form: ab[k - d, j] = N[j - d, j]
            upper[k - d, d:] = band[k + d, lo:hi - d]
        upper[k] += 1e-14 * float(np.abs(upper[k]).max())
        factor = sla.cholesky_banded(upper, check_finite=False)
        return lambda b: sla.cho_solve_banded((factor, False), b, check_finite=False)
    rows = np.tile(np.arange(n), 2 * k + 1)
    cols = np.mod(rows + np.repeat(np.arange(-k, k + 1), n), n)
    mat = sp.csc_matrix((band.ravel(), (rows, cols)), shape=(n, n))
    mat = mat + sp.identity(n, format="csc") * (1e-14 * float(np.abs(band[k]).max()))
    return splu(sp.csc_matrix(mat)).solve


def _solve_rows(cols: np.ndarray, vals: np.ndarray, rhs: np.ndarray, n: int, closed: bool) -> np.ndarray:
    """Least squares for the unknowns of a row-wise basis: all of them (closed), or all but the two ends (open;
    their columns' values already zeroed).

    Normal equations built directly from the rows (no sparse products): factored densely by Cholesky up to
    ``_DENSE_COLUMNS`` unknowns, as a band above; one refinement step on the residual recovers the accuracy the
    squared condition number costs. A singular system (fewer data than unknowns) falls back to an SVD solve.
    """
    k = cols.shape[1] - 1
    lo, hi = (0, n) if closed else (1, n - 1)
    dense = n <= max(_DENSE_COLUMNS, 2 * k + 2)
    ata, atb = _normal(cols, vals, rhs, n, dense)
    try:
        if dense:
            factor = sla.cho_factor(ata[lo:hi, lo:hi], check_finite=False)
            solve = lambda b: sla.cho_solve(factor, b, check_finite=False)  # noqa: E731
        else:
            solve = _band_solver(ata, lo, hi, closed)
        x = np.zeros((n, rhs.shape[1]))
        x[lo:hi] = solve(atb[lo:hi])
        resid = rhs - np.einsum("ij,ijd->id", vals, x[cols])
        x[lo:hi] += solve(_transpose_product(cols, vals, resid, n)[lo:hi])
    except (np.linalg.LinAlgError, RuntimeError, ValueError):
        x = np.full((n, rhs.shape[1]), np.nan)
    if not np.all(np.isfinite(x[lo:hi])):
        return np.linalg.lstsq(_dense_basis(cols, vals, n)[:, lo:hi], rhs, rcond=None)[0]
    return x[lo:hi]


def _dense_basis(cols: np.ndarray, vals: np.ndarray, n: int) -> np.ndarray:
    full = np.zeros((len(cols), n))
    np.add.at(full, (np.repeat(np.arange(len(cols)), cols.shape[1]), cols.ravel()), vals.ravel())
    return full


def solve_interior(target: np.ndarray, n_ctrl: int, params: np.ndarray, degree: int,
                   lo: np.ndarray | None = None, hi: np.ndarray | None = None,
                   weights: np.ndarray | None = None, closed: bool = False) -> np.ndarray:
    """Control points by least squares: open curves keep their ends on the first/last data point, closed
    (periodic) curves solve every point.

    When ``lo``/``hi`` are given and the unconstrained optimum of a small system leaves that box, a bounded
    solve (scipy's ``lsq_linear``) keeps every point inside it, so the result stays a valid op target.
    """
    target = np.asarray(target, dtype=np.float64)
    cols, vals = _rows(n_ctrl, params, degree, closed)
    rhs = target.copy()
    if not closed:
        for end, point in ((0, target[0]), (n_ctrl - 1, target[-1])):
            hit = cols == end
            rhs -= (vals * hit).sum(axis=1)[:, None] * point[None, :]
            vals = np.where(hit, 0.0, vals)
    if weights is not None:
        root = np.sqrt(np.asarray(weights, dtype=np.float64))
        vals = vals * root[:, None]
        rhs = rhs * root[:, None]
    sol = _solve_rows(cols, vals, rhs, n_ctrl, closed)
    if len(sol) <= _DENSE_COLUMNS and lo is not None and hi is not None and (np.any(sol < lo) or np.any(sol > hi)):
        dense = _dense_basis(cols, vals, n_ctrl)[:, (0 if closed else 1):(n_ctrl if closed else n_ctrl - 1)]
        sol = np.column_stack([
            lsq_linear(dense, rhs[:, k], bounds=(lo[k], hi[k]), method="bvls").x for k in range(rhs.shape[1])
        ])
    return sol if closed else np.vstack([target[:1], sol, target[-1:]])


def closed_chord_params(points: np.ndarray) -> np.ndarray:
    """Cumulative chord length around a closed point sequence (closing segment included), in [0, 1)."""
    p = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(np.vstack([p, p[:1]]), axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg)[:-1]]) / seg.sum()


def _project(ctrl: np.ndarray, target: np.ndarray, params: np.ndarray, degree: int,
             closed: bool) -> tuple[np.ndarray, np.ndarray]:
    return spline_foot_points(bspline.make_spline(ctrl, degree, closed), target, params, iterations=2,
                              periodic=closed)


def _ordered(params: np.ndarray, closed: bool) -> np.ndarray:
    if closed:
        return np.mod(params, 1.0)
    params = np.maximum.accumulate(np.clip(params, 0.0, 1.0))
    params[0], params[-1] = 0.0, 1.0
    return params


def fit_curve(target: np.ndarray, n_ctrl: int, degree: int = 3,
              parametrization: Literal["geometric", "index"] = "geometric", iterations: int = 25,
              lo: np.ndarray | None = None, hi: np.ndarray | None = None, rtol: float = 1e-3,
              warm_params: np.ndarray | None = None, closed: bool = False, joint: bool = False,
              bracket: tuple[float, float] | None = None) -> CurveFit:
    """Best control polygon of ``n_ctrl`` points for ordered ``target`` points (``closed``: a periodic curve).

    ``index``: parameters evenly spaced (the paper's index-wise correspondence), distances index-wise.
    ``geometric``: parameters refined by foot points until a round improves the RMS distance by less than
    ``rtol`` (or after ``iterations`` rounds); distances are point-to-curve. Parameter correction is
    start-dependent, so ``warm_params`` (e.g. those of a fit with one control point fewer) are tried as
    a third start; the best start after one solve is refined. ``joint``: small near-exact problems are then finished
    by :func:`joint_refine` (alternating correction creeps; sparse data need the joint step to converge), restarted
    from the parameters of fits with more points while not exact (sparse data have local minima).
    ``bracket = (goal, hopeless)``: a tolerance search's question is only whether the max distance can be met, so
    the refinement stops once the max distance is within ``goal``, or above ``hopeless`` after six rounds.
    """
    target = np.asarray(target, dtype=np.float64)
    m = len(target)
    uniform = np.linspace(0.0, 1.0, m, endpoint=not closed)
    if parametrization == "index":
        ctrl = solve_interior(target, n_ctrl, uniform, degree, lo, hi, closed=closed)
        dist = np.linalg.norm(bspline.make_spline(ctrl, degree, closed)(uniform) - target, axis=1)
        return CurveFit(ctrl, uniform, dist, closed)
    starts = [uniform, closed_chord_params(target) if closed else chord_length_params(target)]
    if warm_params is not None:
        starts.append(np.asarray(warm_params, dtype=np.float64))
    first = [_project(solve_interior(target, n_ctrl, p, degree, lo, hi, closed=closed), target, p, degree, closed)
             for p in starts]
    params, dist = min(first, key=lambda pd: float(np.sum(pd[1] ** 2)))
    fit: CurveFit | None = None
    step = 1.0  # over-relaxation of the parameter update: correction creeps along the curve, so steps that
    for rnd in range(max(1, iterations)):  # keep improving grow; a step that does not is retried plainly
        params = _ordered(params, closed)
        ctrl = solve_interior(target, n_ctrl, params, degree, lo, hi, closed=closed)
        new_params, dist = _project(ctrl, target, params, degree, closed)
        candidate = CurveFit(ctrl, new_params, dist, closed)
        improved = fit is None or candidate.rms < fit.rms * (1 - rtol)
        if fit is None or candidate.rms < fit.rms:
            fit = candidate
        if bracket is not None and (dist.max() <= bracket[0] or (rnd >= 5 and fit.distances.max() > bracket[1])):
            fit = candidate if dist.max() <= bracket[0] else fit
            break
        if not improved:
            if step == 1.0:
                break
            step, params = 1.0, fit.params
            continue
        delta = new_params - params
        if closed:
            delta = np.mod(delta + 0.5, 1.0) - 0.5
        params = params + step * delta
        step = min(4.0, 1.5 * step)
    diag = float(np.linalg.norm(np.ptp(target, axis=0)))
    if joint and len(target) <= _JOINT_POINTS and fit.rms <= _JOINT_RMS * diag:
        fit = joint_refine(target, fit, degree, lo, hi)
        if warm_params is not None:  # the joint step finds the basin of its start: also try the cold starts
            cold = fit_curve(target, n_ctrl, degree, parametrization, iterations, lo, hi, rtol, None, closed, True)
            fit = cold if cold.rms < fit.rms else fit
        else:
            fit = _finer_starts(target, fit, degree, lo, hi, _EXACT * diag)
    return fit


def _joint_from(target: np.ndarray, n_ctrl: int, params: np.ndarray, degree: int, lo: np.ndarray | None,
                hi: np.ndarray | None, closed: bool) -> CurveFit:
    """One least-squares solve at ``params``, foot points, then the joint step."""
    params = _ordered(np.array(params, dtype=np.float64), closed)
    ctrl = solve_interior(target, n_ctrl, params, degree, lo, hi, closed=closed)
    foot, dist = _project(ctrl, target, params, degree, closed)
    return joint_refine(target, CurveFit(ctrl, foot, dist, closed), degree, lo, hi)


def _finer_starts(target: np.ndarray, fit: CurveFit, degree: int, lo: np.ndarray | None, hi: np.ndarray | None,
                  exact: float) -> CurveFit:
    """The best of ``fit`` and joint fits started from the parameters of fits with more control points.

    On sparse data the joint step from a uniform or chord-length start often ends in a local minimum of the
    parametrisation (the data between uneven gaps are matched at shifted parameters). A curve with more points
    absorbs that shift, so its foot points lie nearer the true ones: each of ``n + 1, n + 2, n + 4, n + 8`` points
    (while the joint problem stays over-determined) is fitted cold, and its parameters start the ``n``-point
    joint step. Stops once a fit is exact (RMS within ``exact``)."""
    m, dim = target.shape
    n, closed = len(fit.ctrl), fit.closed
    free = (lambda k: k * dim + m) if closed else (lambda k: (k - 2) * dim + m - 2)
    uniform = np.linspace(0.0, 1.0, m, endpoint=not closed)
    for extra in _FINER:
        if fit.rms <= exact or free(n + extra) >= m * dim:
            break
        finer = _joint_from(target, n + extra, uniform, degree, lo, hi, closed)
        trial = _joint_from(target, n, finer.params, degree, lo, hi, closed)
        fit = trial if trial.rms < fit.rms else fit
    return fit


def joint_refine(target: np.ndarray, fit: CurveFit, degree: int = 3, lo: np.ndarray | None = None,
                 hi: np.ndarray | None = None, max_evaluations: int = 60) -> CurveFit:
    """Minimise the squared foot-point distances over control points and parameters together (Levenberg-
    Marquardt, analytic dense Jacobian): converges where alternating correction creeps (sparse data, true
    counts). Open curves keep their end points and end parameters. Returns the better of ``fit`` and the
    result (its parameters re-projected), so the RMS never grows."""
    p = np.asarray(target, dtype=np.float64)
    m, dim = p.shape
    n, closed = len(fit.ctrl), fit.closed
    inner = slice(0, n) if closed else slice(1, n - 1)
    free_u = slice(0, m) if closed else slice(1, m - 1)
    n_free, m_free = len(range(n)[inner]), len(range(m)[free_u])
    if n_free * dim + m_free >= m * dim:
        return fit
    ctrl0 = np.array(fit.ctrl, dtype=np.float64)

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ctrl = ctrl0.copy()
        ctrl[inner] = x[:n_free * dim].reshape(n_free, dim)
        u = np.array(fit.params, dtype=np.float64)
        u[free_u] = x[n_free * dim:]
        return ctrl, (np.mod(u, 1.0) if closed else np.clip(u, 0.0, 1.0))

    def residual(x: np.ndarray) -> np.ndarray:
        ctrl, u = unpack(x)
        return (bspline.make_spline(ctrl, degree, closed)(u) - p).ravel()

    def jacobian(x: np.ndarray) -> np.ndarray:
        ctrl, u = unpack(x)
        cols, vals = _rows(n, u, degree, closed)
        basis = _dense_basis(cols, vals, n)[:, inner]  # (m, n_free)
        jac = np.zeros((m, dim, n_free * dim + m_free))
        for k in range(dim):
            jac[:, k, k:n_free * dim:dim] = basis
        tangent = bspline.make_spline(ctrl, degree, closed)(u, 1)
        rows = np.arange(m)[free_u]
        jac[rows, :, n_free * dim + np.arange(m_free)] = tangent[rows]
        return jac.reshape(m * dim, -1)

    x0 = np.concatenate([ctrl0[inner].ravel(), np.asarray(fit.params, dtype=np.float64)[free_u]])
    try:
        sol = least_squares(residual, x0, jac=jacobian, method="lm", max_nfev=max_evaluations, xtol=1e-15,
                            ftol=1e-15, gtol=1e-15)
    except (ValueError, np.linalg.LinAlgError):
        return fit
    ctrl, u = unpack(sol.x)
    if not np.all(np.isfinite(ctrl)) or (lo is not None and hi is not None and (np.any(ctrl < lo) or
                                                                                np.any(ctrl > hi))):
        return fit
    u = u if closed else np.maximum.accumulate(u)
    params, dist = _project(ctrl, p, u, degree, closed)
    out = CurveFit(ctrl, params, dist, closed)
    return out if out.rms < fit.rms else fit


def minimax_refine(target: np.ndarray, fit: CurveFit, degree: int = 3, iterations: int = 30,
                   lo: np.ndarray | None = None, hi: np.ndarray | None = None, goal: float | None = None) -> CurveFit:
    """Lower the *maximum* distance of a fit (Lawson's iteratively reweighted least squares).

    Least squares minimises the RMS; a CAD tolerance is a maximum. Lawson's weights (multiplied by each
    point's current distance) drive the weighted solution toward the minimax one; parameters follow by
    foot points. Returns the iterate with the smallest maximum distance, as soon as it is within ``goal`` (when
    given) or after twelve rounds without a new smallest.
    """
    n_ctrl, closed = len(fit.ctrl), fit.closed
    weights = np.full(len(target), 1.0 / len(target))
    best, params, dist, since = fit, fit.params, fit.distances, 0
    for _ in range(iterations):
        weights = weights * np.maximum(dist, 1e-300)
        total = weights.sum()
        if not np.isfinite(total) or total <= 0:
            break
        weights /= total
        params = _ordered(params, closed)
        ctrl = solve_interior(target, n_ctrl, params, degree, lo, hi, weights=weights, closed=closed)
        params, dist = _project(ctrl, target, params, degree, closed)
        if dist.max() < best.distances.max():
            best, since = CurveFit(ctrl, params, dist, closed), 0
        else:
            since += 1
        if (goal is not None and best.distances.max() <= goal) or since >= 12:
            break
    return best


def tangent_refine(target: np.ndarray, fit: CurveFit, degree: int = 3, lo: np.ndarray | None = None,
                   hi: np.ndarray | None = None, iterations: int = 40, rtol: float = 1e-6,
                   free_ends: bool = False) -> CurveFit:
    """Gauss-Newton on control points and parameters together, with the parameters eliminated: each round
    solves the control points for the squared distances with each point's tangential component weighted by
    ``lam`` (0: the normal distance only, the full Gauss-Newton step; 1: plain alternating correction), then
    re-projects the foot points; ``lam`` shrinks while the RMS drops and grows when it does not (Levenberg-
    Marquardt damping). Converges where alternating correction creeps, at the cost of a dense solve of the
    coupled coordinates (for at most ``_DENSE_COLUMNS`` control points). ``free_ends``: an open curve's end
    control points are unknowns too (noisy end samples are no better than the others). Returns the best fit
    (never worse)."""
    p = np.asarray(target, dtype=np.float64)
    m, dim = p.shape
    n, closed = len(fit.ctrl), fit.closed
    inner = np.arange(n) if closed or free_ends else np.arange(1, n - 1)
    if n > _DENSE_COLUMNS or len(inner) * dim >= m * (dim - 1):
        return fit
    ends = np.array([0, m - 1]) if free_ends and not closed else np.zeros(0, dtype=np.int64)

    def pinned(ctrl: np.ndarray, params: np.ndarray, dist: np.ndarray) -> CurveFit:
        """With free end control points the first and last samples stay at the curve's ends (parameters 0
        and 1, their whole offset counted): otherwise nothing would hold the ends beyond the data."""
        if ends.size:
            params, dist = params.copy(), dist.copy()
            params[ends] = (0.0, 1.0)
            dist[ends] = np.linalg.norm(ctrl[[0, n - 1]] - p[ends], axis=1)
        return CurveFit(ctrl, params, dist, closed)

    best, lam = pinned(fit.ctrl, fit.params, fit.distances), 0.1
    for _ in range(iterations):
        spline = bspline.make_spline(best.ctrl, degree, closed)
        tangent = spline(best.params, 1)
        unit = tangent / np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-300)
        unit[ends] = 0.0  # the end samples' tangential offsets count too
        root = np.eye(dim)[None] - (1.0 - math.sqrt(lam)) * unit[:, :, None] * unit[:, None, :]  # (m, dim, dim)
        cols, vals = _rows(n, best.params, degree, closed)
        basis = _dense_basis(cols, vals, n)
        rhs = p - (0.0 if closed or free_ends else basis[:, [0, n - 1]] @ best.ctrl[[0, n - 1]])
        design = np.einsum("iab,ik->iakb", root, basis[:, inner]).reshape(m * dim, len(inner) * dim)
        sol = np.linalg.lstsq(design, np.einsum("iab,ib->ia", root, rhs).ravel(), rcond=None)[0]
        ctrl = best.ctrl.copy()
        ctrl[inner] = sol.reshape(len(inner), dim)
        if not np.all(np.isfinite(ctrl)) or (lo is not None and hi is not None and (np.any(ctrl < lo) or
                                                                                    np.any(ctrl > hi))):
            lam = min(1.0, 4.0 * lam)
            continue
        params, dist = _project(ctrl, p, _ordered(best.params.copy(), closed), degree, closed)
        trial = pinned(ctrl, params, dist)
        if trial.rms < best.rms:
            gain = 1.0 - trial.rms / best.rms
            best, lam = trial, max(1e-4, 0.3 * lam)
            if gain < rtol:
                break
        elif lam >= 1.0:
            break
        else:
            lam = min(1.0, 4.0 * lam)
    return best


def warp_basis(m: int, terms: int) -> np.ndarray:
    """``(m, terms)`` smooth warps of evenly spaced parameters ``s`` that keep both ends:
    ``s (1 - s) P_j(2 s - 1)`` with ``P_j`` the Legendre polynomials (well conditioned, nested in ``terms``)."""
    s = np.linspace(0.0, 1.0, m)
    legendre = np.polynomial.legendre.legvander(2.0 * s - 1.0, max(terms - 1, 0))[:, :terms]
    return (s * (1.0 - s))[:, None] * legendre


def warped_fit(target: np.ndarray, n_ctrl: int, terms: int, degree: int = 3,
               starts: tuple[np.ndarray, ...] = ()) -> tuple[CurveFit, np.ndarray]:
    """Least squares of an open curve to points sampled at a smooth warp of evenly spaced parameters.

    Sample ``i`` of ``m`` is matched index-wise to the curve at ``u_i = s_i + W(s_i) c`` (``s_i = i / (m - 1)``,
    ``W`` = :func:`warp_basis` with ``terms`` columns): ``terms = 0`` is the paper's own evenly spaced
    correspondence, each further term a smoother-to-rougher reparametrisation (``u = s^2`` is one term). Every
    control point is an unknown, the ends included. The warp coefficients ``c`` are found by Levenberg-Marquardt
    with the control points eliminated (variable projection), from zero and from each of ``starts`` (warp
    coefficients, e.g. a fit's with fewer terms). Returns the fit (distances index-wise) and its ``c``.
    """
    p = np.asarray(target, dtype=np.float64)
    m = len(p)
    s = np.linspace(0.0, 1.0, m)
    warp = warp_basis(m, terms)
    memo: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}

    def solve(c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Control points, parameters, residuals and the basis' orthonormal range at warp ``c``."""
        key = np.asarray(c, dtype=np.float64).tobytes()
        if key not in memo:
            memo.clear()
            u = np.maximum.accumulate(np.clip(s + warp @ c, 0.0, 1.0))
            basis = _dense_basis(*_rows(n_ctrl, u, degree, False), n_ctrl)
            ctrl = np.linalg.lstsq(basis, p, rcond=None)[0]
            memo[key] = (ctrl, u, basis @ ctrl - p, np.linalg.qr(basis)[0])
        return memo[key]

    def jacobian(c: np.ndarray) -> np.ndarray:
        """Kaufman's variable-projection Jacobian: the curve's motion along its tangent under each warp
        term, with the part the control points absorb projected out."""
        ctrl, u, _, q = solve(c)
        moved = bspline.make_spline(ctrl, degree, False)(u, 1)[:, :, None] * warp[:, None, :]  # (m, dim, terms)
        moved -= np.einsum("ik,kdj->idj", q, np.einsum("ik,idj->kdj", q, moved))
        return moved.reshape(-1, terms)

    best = np.zeros(terms)
    if terms:
        best_sse = math.inf
        for start in (np.zeros(terms), *starts):
            c0 = np.zeros(terms)
            c0[:min(terms, len(start))] = np.asarray(start, dtype=np.float64)[:terms]
            try:
                sol = least_squares(lambda c: solve(c)[2].ravel(), c0, jac=jacobian, method="lm", xtol=1e-10,
                                    ftol=1e-10)
            except (ValueError, np.linalg.LinAlgError):
                continue
            if np.all(np.isfinite(sol.x)) and 2.0 * sol.cost < best_sse:
                best, best_sse = sol.x, 2.0 * sol.cost
    ctrl, u, resid, _ = solve(best)
    return CurveFit(ctrl, u, np.linalg.norm(resid, axis=1), False), best
