"""Chaikin corner cutting: open (end-point preserving) and closed polygons.

One step maps ``P0..P[n-1]`` to ``P0, (P0+P1)/2, 3/4 P1 + 1/4 P2, 1/4 P1 + 3/4 P2, ..., (P[n-2]+P[n-1])/2,
P[n-1]`` (``2n - 2`` points). This is exactly midpoint knot insertion on the clamped uniform quadratic
B-spline of the same control points, so every refinement describes the same curve and the polygons
converge to it: the Chaikin limit is :func:`gsr_cad.geometry.bspline.evaluate` with ``degree=limit_degree``.
On a closed polygon every edge is cut at 1/4 and 3/4 (``2n`` points): the limit is the periodic uniform
quadratic B-spline (:func:`gsr_cad.geometry.bspline.make_spline` with ``closed=True``).
Refinement matrices depend only on the point count and are cached as read-only sparse matrices.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.sparse as sp

from ..errors import InputError

limit_degree: int = 2


def _check_n(n_ctrl: int) -> int:
    if isinstance(n_ctrl, bool) or not isinstance(n_ctrl, (int, np.integer)) or n_ctrl < limit_degree + 1:
        raise InputError(f"Chaikin refinement needs at least {limit_degree + 1} points, got {n_ctrl!r}")
    return int(n_ctrl)


def _check_levels(levels: int) -> int:
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) or levels < 0:
        raise InputError(f"refinement levels must be an integer >= 0, got {levels!r}")
    return int(levels)


def _freeze(m: sp.csr_matrix) -> sp.csr_matrix:
    m.sum_duplicates()
    m.sort_indices()
    for a in (m.data, m.indices, m.indptr):
        a.setflags(write=False)
    return m


def _one_level(n: int) -> sp.csr_matrix:
    """The ``(2n - 2, n)`` matrix of a single Chaikin step on ``n`` points."""
    # Interior edges i = 1..n-3 give two rows each (3/4, 1/4) and (1/4, 3/4); the end edges give midpoints.
    inner = np.arange(1, n - 2)
    rows = np.concatenate([[0, 1, 1], 2 * inner, 2 * inner, 2 * inner + 1, 2 * inner + 1,
                           [2 * n - 4, 2 * n - 4, 2 * n - 3]])
    cols = np.concatenate([[0, 0, 1], inner, inner + 1, inner, inner + 1, [n - 2, n - 1, n - 1]])
    vals = np.concatenate([[1.0, 0.5, 0.5], np.full(inner.size, 0.75), np.full(inner.size, 0.25),
                           np.full(inner.size, 0.25), np.full(inner.size, 0.75), [0.5, 0.5, 1.0]])
    return sp.csr_matrix((vals, (rows, cols)), shape=(2 * n - 2, n))


@functools.lru_cache(maxsize=256)
def _refinement(n_ctrl: int, levels: int) -> sp.csr_matrix:
    if levels == 0:
        return _freeze(sp.identity(n_ctrl, format="csr"))
    prev = _refinement(n_ctrl, levels - 1)
    return _freeze(sp.csr_matrix(_one_level(prev.shape[0]) @ prev))


def refinement_matrix(n_ctrl: int, levels: int = 1) -> sp.csr_matrix:
    """Cached sparse ``(2**levels * (n_ctrl - 2) + 2, n_ctrl)`` matrix of ``levels`` Chaikin steps (read-only)."""
    return _refinement(_check_n(n_ctrl), _check_levels(levels))


def refine(points: np.ndarray, levels: int = 1) -> np.ndarray:
    """Apply ``levels`` Chaikin steps to an open polygon ``(n, dim)``, keeping both end points."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] < 1:
        raise InputError(f"Chaikin refinement needs an (n, dim) point array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise InputError("Chaikin refinement needs finite points")
    return np.asarray(refinement_matrix(len(p), levels) @ p)


@functools.lru_cache(maxsize=256)
def _closed_refinement(n_ctrl: int, levels: int) -> sp.csr_matrix:
    if levels == 0:
        return _freeze(sp.identity(n_ctrl, format="csr"))
    prev = _closed_refinement(n_ctrl, levels - 1)
    n = prev.shape[0]
    i = np.arange(n)
    rows = np.concatenate([2 * i, 2 * i, 2 * i + 1, 2 * i + 1])
    cols = np.concatenate([i, (i + 1) % n, i, (i + 1) % n])
    vals = np.concatenate([np.full(n, 0.75), np.full(n, 0.25), np.full(n, 0.25), np.full(n, 0.75)])
    return _freeze(sp.csr_matrix(sp.csr_matrix((vals, (rows, cols)), shape=(2 * n, n)) @ prev))


def refine_closed(points: np.ndarray, levels: int = 1) -> np.ndarray:
    """Apply ``levels`` closed Chaikin steps to a closed polygon ``(n, dim)`` (``2**levels * n`` points)."""
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] < 1 or not np.all(np.isfinite(p)):
        raise InputError(f"Chaikin refinement needs a finite (n, dim) point array, got shape {p.shape}")
    return np.asarray(_closed_refinement(_check_n(len(p)), _check_levels(levels)) @ p)
