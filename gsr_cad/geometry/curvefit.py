"""Least-squares placement of a curve's control points (the polish the paper lacks).

Curve points are linear in the control points, so for a fixed count and fixed parameters the best
control points solve a linear least-squares problem: on an open curve the end points stay on the first and
last data points (the paper's clamped template) and the interior is solved; on a closed (periodic) curve
every control point is free. With ``parametrization="geometric"`` the parameters are refined by foot-point
projection (alternating with the solve), which removes the paper's assumption that the data are evenly
spaced in parameter; the better of a uniform and a chord-length start (after one solve) is refined. Large
systems (many control points) are solved through their sparse banded normal equations.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import scipy.sparse as sp
import scipy.linalg as sla
from scipy.optimize import lsq_linear
from scipy.sparse.linalg import splu

from . import bspline
from .distance import chord_length_params, spline_foot_points

_DENSE_COLUMNS = 64  # up to this many unknowns the normal matrix is factored densely


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


def _solve(a: sp.csr_array, rhs: np.ndarray) -> np.ndarray:
    """Least squares ``a x = rhs`` for a sparse B-spline basis ``a``, through its normal equations.

    The normal matrix is banded and built sparse (no multi-threaded BLAS on tall matrices, which costs more
    than it saves on a shared machine); small systems are factored densely by Cholesky, large ones by sparse
    LU. One refinement step on the residual recovers the accuracy the squared condition number costs. An
    SVD solve covers a singular normal matrix (fewer data than unknowns).
    """
    ata = sp.csc_matrix(a.T @ a)
    atb = np.asarray(a.T @ rhs)
    try:
        if ata.shape[0] <= _DENSE_COLUMNS:
            factor = sla.cho_factor(ata.toarray(), check_finite=False)
            solve = lambda b: sla.cho_solve(factor, b, check_finite=False)  # noqa: E731
        else:
            lu = splu(ata + sp.identity(ata.shape[0], format="csc") * (1e-14 * float(abs(ata.diagonal()).max())))
            solve = lu.solve
        x = solve(atb)
        x += solve(np.asarray(a.T @ (rhs - a @ x)))
    except (np.linalg.LinAlgError, RuntimeError):
        x = np.full(atb.shape, np.nan)
    if not np.all(np.isfinite(x)):
        return np.linalg.lstsq(a.toarray(), rhs, rcond=None)[0]
    return x


def solve_interior(target: np.ndarray, n_ctrl: int, params: np.ndarray, degree: int,
                   lo: np.ndarray | None = None, hi: np.ndarray | None = None,
                   weights: np.ndarray | None = None, closed: bool = False) -> np.ndarray:
    """Control points by least squares: open curves keep their ends on the first/last data point, closed
    (periodic) curves solve every point.

    When ``lo``/``hi`` are given and the unconstrained optimum of a small system leaves that box, a bounded
    solve (scipy's ``lsq_linear``) keeps every point inside it, so the result stays a valid op target.
    """
    basis = bspline.form_design(n_ctrl, params, degree, closed=closed)
    if closed:
        inner, rhs = basis, np.array(target, dtype=np.float64)
    else:
        col = basis.tocsc()
        first, last = col[:, [0]].toarray(), col[:, [n_ctrl - 1]].toarray()
        rhs = target - first * target[0] - last * target[-1]
        inner = sp.csr_array(col[:, 1:-1])
    if weights is not None:
        root = np.sqrt(weights)
        inner = sp.csr_array(sp.diags_array(root) @ inner)
        rhs = rhs * root[:, None]
    sol = _solve(inner, rhs)
    small = inner.shape[1] <= _DENSE_COLUMNS
    if small and lo is not None and hi is not None and (np.any(sol < lo) or np.any(sol > hi)):
        dense = inner.toarray()
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
              warm_params: np.ndarray | None = None, closed: bool = False) -> CurveFit:
    """Best control polygon of ``n_ctrl`` points for ordered ``target`` points (``closed``: a periodic curve).

    ``index``: parameters evenly spaced (the paper's index-wise correspondence), distances index-wise.
    ``geometric``: parameters refined by foot points until a round improves the RMS distance by less than
    ``rtol`` (or after ``iterations`` rounds); distances are point-to-curve. Parameter correction is
    start-dependent, so ``warm_params`` (e.g. those of a fit with one control point fewer) are tried as
    a third start; the best start after one solve is refined.
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
    for _ in range(max(1, iterations)):
        params = _ordered(params, closed)
        ctrl = solve_interior(target, n_ctrl, params, degree, lo, hi, closed=closed)
        new_params, dist = _project(ctrl, target, params, degree, closed)
        candidate = CurveFit(ctrl, new_params, dist, closed)
        improved = fit is None or candidate.rms < fit.rms * (1 - rtol)
        if fit is None or candidate.rms < fit.rms:
            fit = candidate
        if not improved:
            break
        params = new_params
    return fit


def minimax_refine(target: np.ndarray, fit: CurveFit, degree: int = 3, iterations: int = 30,
                   lo: np.ndarray | None = None, hi: np.ndarray | None = None) -> CurveFit:
    """Lower the *maximum* distance of a fit (Lawson's iteratively reweighted least squares).

    Least squares minimises the RMS; a CAD tolerance is a maximum. Lawson's weights (multiplied by each
    point's current distance) drive the weighted solution toward the minimax one; parameters follow by
    foot points. Returns the iterate with the smallest maximum distance.
    """
    n_ctrl, closed = len(fit.ctrl), fit.closed
    weights = np.full(len(target), 1.0 / len(target))
    best, params, dist = fit, fit.params, fit.distances
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
            best = CurveFit(ctrl, params, dist, closed)
    return best
