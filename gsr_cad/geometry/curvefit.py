"""Least-squares placement of a curve's control points (the polish the paper lacks).

Curve points are linear in the control points, so for a fixed count and fixed parameters the best
interior control points solve a linear least-squares problem (end points stay on the first and last data
points, as in the paper's clamped template). With ``parametrization="geometric"`` the parameters are
refined by foot-point projection (alternating with the solve), which removes the paper's assumption that
the data are evenly spaced in parameter; the better of a uniform and a chord-length start (after one solve) is refined.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from scipy.optimize import lsq_linear

from . import bspline
from .distance import chord_length_params, foot_points


@dataclasses.dataclass(frozen=True)
class CurveFit:
    """A fitted control polygon and how well it fits (distances are absolute, per data point)."""

    ctrl: np.ndarray
    params: np.ndarray
    distances: np.ndarray

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.distances ** 2)))


def solve_interior(target: np.ndarray, n_ctrl: int, params: np.ndarray, degree: int,
                   lo: np.ndarray | None = None, hi: np.ndarray | None = None,
                   weights: np.ndarray | None = None) -> np.ndarray:
    """Control points with ends on the first/last data point and the interior by least squares.

    When ``lo``/``hi`` are given and the unconstrained optimum leaves that box, a bounded solve
    (scipy's ``lsq_linear``) keeps every point inside it, so the result stays a valid op target.
    """
    basis = bspline.basis_matrix(n_ctrl, params, degree)
    ends = np.outer(basis[:, 0], target[0]) + np.outer(basis[:, -1], target[-1])
    inner = basis[:, 1:-1]
    rhs = target - ends
    if weights is not None:
        root = np.sqrt(weights)[:, None]
        inner, rhs = inner * root, rhs * root
    sol, *_ = np.linalg.lstsq(inner, rhs, rcond=None)
    if lo is not None and hi is not None and (np.any(sol < lo) or np.any(sol > hi)):
        sol = np.column_stack([
            lsq_linear(inner, rhs[:, k], bounds=(lo[k], hi[k]), method="bvls").x for k in range(rhs.shape[1])
        ])
    return np.vstack([target[:1], sol, target[-1:]])


def fit_curve(target: np.ndarray, n_ctrl: int, degree: int = 3,
              parametrization: Literal["geometric", "index"] = "geometric", iterations: int = 25,
              lo: np.ndarray | None = None, hi: np.ndarray | None = None, rtol: float = 1e-3,
              warm_params: np.ndarray | None = None) -> CurveFit:
    """Best control polygon of ``n_ctrl`` points for ordered ``target`` points.

    ``index``: parameters evenly spaced (the paper's index-wise correspondence), distances index-wise.
    ``geometric``: parameters refined by foot points until a round improves the RMS distance by less than
    ``rtol`` (or after ``iterations`` rounds); distances are point-to-curve. Parameter correction is
    start-dependent, so ``warm_params`` (e.g. those of a fit with one control point fewer) are tried as
    a third start; the best start after one solve is refined.
    """
    target = np.asarray(target, dtype=np.float64)
    m = len(target)
    uniform = np.linspace(0.0, 1.0, m)
    if parametrization == "index":
        ctrl = solve_interior(target, n_ctrl, uniform, degree, lo, hi)
        dist = np.linalg.norm(bspline.evaluate(ctrl, uniform, degree) - target, axis=1)
        return CurveFit(ctrl, uniform, dist)
    starts = [uniform, chord_length_params(target)]
    if warm_params is not None:
        starts.append(np.asarray(warm_params, dtype=np.float64))
    first = [foot_points(solve_interior(target, n_ctrl, p, degree, lo, hi), target, p, degree=degree, iterations=2)
             for p in starts]
    params, dist = min(first, key=lambda pd: float(np.sum(pd[1] ** 2)))
    fit: CurveFit | None = None
    for _ in range(max(1, iterations)):
        params = np.maximum.accumulate(np.clip(params, 0.0, 1.0))
        params[0], params[-1] = 0.0, 1.0
        ctrl = solve_interior(target, n_ctrl, params, degree, lo, hi)
        new_params, dist = foot_points(ctrl, target, params, degree=degree, iterations=2)
        candidate = CurveFit(ctrl, new_params, dist)
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
    n_ctrl = len(fit.ctrl)
    weights = np.full(len(target), 1.0 / len(target))
    best, params, dist = fit, fit.params, fit.distances
    for _ in range(iterations):
        weights = weights * np.maximum(dist, 1e-300)
        total = weights.sum()
        if not np.isfinite(total) or total <= 0:
            break
        weights /= total
        params = np.maximum.accumulate(np.clip(params, 0.0, 1.0))
        params[0], params[-1] = 0.0, 1.0
        ctrl = solve_interior(target, n_ctrl, params, degree, lo, hi, weights=weights)
        params, dist = foot_points(ctrl, target, params, degree=degree, iterations=2)
        if dist.max() < best.distances.max():
            best = CurveFit(ctrl, params, dist)
    return best
