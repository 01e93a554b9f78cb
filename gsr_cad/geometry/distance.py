"""Distances between curves and points (numpy/scipy only).

Curves: the paper's index-wise distance (curve sampled as often as the data, compared sample by sample),
chord-length parameters for data that is not evenly spaced, orthogonal foot points on a clamped uniform
B-spline (vectorized safeguarded Newton) and exact point-to-polyline distances.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from ..errors import InputError
from .bspline import _check_ctrl, _check_degree, _check_params, _knots

_DENSE_PAIRS = 1 << 13  # point-segment pairs handled by plain broadcasting before the KD-tree prunes
_PAIR_BLOCK = 1 << 20  # candidate pairs processed at once by the pruned search (bounds memory)


def _as_points(points: np.ndarray, what: str, dim: int | None = None) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] < 1 or (dim is not None and p.shape[1] != dim):
        want = f"(n, {dim})" if dim is not None else "(n, dim)"
        raise InputError(f"{what} must be an {want} array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise InputError(f"{what} must be finite")
    return p


def _check_count(value: int, what: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{what} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def index_wise(samples: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Euclidean distance between ``samples[i]`` and ``target[i]`` for every ``i`` (the paper's fitness terms)."""
    s, t = np.asarray(samples, dtype=np.float64), np.asarray(target, dtype=np.float64)
    if s.shape != t.shape or s.ndim != 2:
        raise InputError(f"index-wise distance needs two (n, dim) arrays of one shape, got {s.shape} and {t.shape}")
    return np.sqrt(np.einsum("ij,ij->i", s - t, s - t))


def chord_length_params(points: np.ndarray) -> np.ndarray:
    """Cumulative chord length of an ordered point sequence, scaled to [0, 1] (first 0, last exactly 1)."""
    p = _as_points(points, "points")
    if len(p) < 2:
        raise InputError("chord-length parameters need at least 2 points")
    seg = np.sqrt(np.einsum("ij,ij->i", np.diff(p, axis=0), np.diff(p, axis=0)))
    total = seg.sum()
    if not total > 0.0:
        raise InputError("chord-length parameters need points that do not all coincide")
    out = np.concatenate([[0.0], np.cumsum(seg)]) / total
    out[-1] = 1.0
    return out


def foot_points(ctrl: np.ndarray, points: np.ndarray, params0: np.ndarray, degree: int = 3,
                iterations: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Project each point onto the clamped uniform curve, starting from ``params0``; returns ``(params, distances)``.

    See :func:`spline_foot_points` (this is it for a clamped uniform B-spline of ``ctrl``).
    """
    degree = _check_degree(degree)
    c = _check_ctrl(ctrl, degree)
    p = _as_points(points, "points", c.shape[1])
    t = _check_params(params0)
    if t.shape != (len(p),):
        raise InputError(f"need one start parameter per point, got {t.size} for {len(p)} points")
    return spline_foot_points(BSpline(_knots(len(c), degree), c, degree), p, t, _check_count(iterations, "iterations", 0))


def spline_foot_points(spline: BSpline, p: np.ndarray, t: np.ndarray, iterations: int = 4,
                       periodic: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Foot points of ``p`` on ``spline`` (domain [0, 1]) from start parameters ``t``: ``(params, distances)``.

    Each iteration takes a Newton step on ``|C(t) - p|^2`` (Gauss-Newton where the Newton model is not
    convex), clipped to [0, 1] (wrapped modulo 1 when ``periodic``), and keeps the best of the full, half
    and quarter step or the current parameter, so distances never grow. All points are handled at once.
    """
    degree = spline.k
    d1 = lambda x: spline(x, 1)  # noqa: E731 - pointwise derivatives also work across repeated (corner) knots
    d2 = (lambda x: spline(x, 2)) if degree >= 2 else None
    t = np.asarray(t, dtype=np.float64)
    pos = spline(t)
    dist = np.linalg.norm(pos - p, axis=1)
    fractions = np.array([1.0, 0.5, 0.25])[:, None]
    rows = np.arange(len(p))
    for _ in range(iterations):
        r = pos - p
        v1 = d1(t)
        grad = np.einsum("ij,ij->i", r, v1)
        gn = np.einsum("ij,ij->i", v1, v1)
        hess = gn + (np.einsum("ij,ij->i", r, d2(t)) if d2 is not None else 0.0)
        hess = np.where(hess > 1e-12 * gn, hess, gn)
        step = -np.divide(grad, hess, out=np.zeros_like(grad), where=hess > 0.0)
        cand = t[None, :] + fractions * step[None, :]
        cand = np.mod(cand, 1.0) if periodic else np.clip(cand, 0.0, 1.0)
        cpos = spline(cand.ravel()).reshape(len(fractions), len(p), p.shape[1])
        cdist = np.linalg.norm(cpos - p[None], axis=2)
        best = np.argmin(cdist, axis=0)
        better = cdist[best, rows] <= dist
        t = np.where(better, cand[best, rows], t)
        dist = np.where(better, cdist[best, rows], dist)
        pos = np.where(better[:, None], cpos[best, rows], pos)
    return t, dist


def point_to_curve(ctrl: np.ndarray, points: np.ndarray, degree: int = 3, dense: int = 2048,
                   seeds: int = 6) -> np.ndarray:
    """Geometric distance of each point to the clamped uniform B-spline of ``ctrl`` (see :func:`point_to_spline`)."""
    degree = _check_degree(degree)
    c = _check_ctrl(ctrl, degree)
    p = _as_points(points, "points", c.shape[1])
    dense = _check_count(dense, "dense", 2)
    return point_to_spline(BSpline(_knots(len(c), degree), c, degree), p, dense=dense, seeds=seeds)


def point_to_spline(spline: BSpline, points: np.ndarray, periodic: bool = False, dense: int = 2048,
                    seeds: int = 6) -> np.ndarray:
    """Geometric distance of each point to a B-spline curve on [0, 1].

    Foot points are refined from the ``seeds`` nearest of ``dense`` curve samples and the smallest
    distance is kept: one seed can sit on the wrong branch where the curve passes close to itself, and
    every refined foot point is a true curve point, so the minimum is never an underestimate.
    """
    p = np.asarray(points, dtype=np.float64)
    k = int(min(max(1, seeds), dense))
    grid = np.linspace(0.0, 1.0, dense, endpoint=not periodic)
    _, idx = cKDTree(spline(grid)).query(p, k=k)
    idx = np.asarray(idx).reshape(len(p), k)
    dist = spline_foot_points(spline, np.repeat(p, k, axis=0), grid[idx.ravel()], periodic=periodic)[1]
    return dist.reshape(len(p), k).min(axis=1)


def data_model(points: np.ndarray, closed: bool = False, corners: np.ndarray | None = None,
               per_segment: int = 8) -> np.ndarray:
    """A dense polyline through the data: centripetal Catmull-Rom pieces between consecutive points.

    The local model the curve -> data distance is measured against: a smooth curve through sparse samples
    deviates from their chords by the sagitta, but not from this model. End points and ``corners`` (indices)
    are kept sharp (the missing neighbour is the reflection of the next point). ``per_segment`` samples per
    piece; 1 gives the data's own polyline.
    """
    p = np.asarray(points, dtype=np.float64)
    m = len(p)
    if per_segment <= 1 or m < 3:
        return np.vstack([p, p[:1]]) if closed else p
    i1 = np.arange(m) if closed else np.arange(m - 1)
    i2 = (i1 + 1) % m
    p1, p2 = p[i1], p[i2]
    p0 = p[(i1 - 1) % m].copy()
    p3 = p[(i2 + 1) % m].copy()
    sharp = np.zeros(m, dtype=bool)
    if corners is not None and len(corners):
        sharp[np.asarray(corners, dtype=np.int64) % m] = True
    if not closed:
        sharp[0] = sharp[-1] = True
    left, right = sharp[i1], sharp[i2]
    p0[left] = 2.0 * p1[left] - p2[left]
    p3[right] = 2.0 * p2[right] - p1[right]

    def knot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.maximum(np.sqrt(np.linalg.norm(b - a, axis=1)), 1e-300)[:, None]

    t1 = knot(p0, p1)
    t2 = t1 + knot(p1, p2)
    t3 = t2 + knot(p2, p3)
    u = np.linspace(0.0, 1.0, per_segment, endpoint=False)[None, :]
    t = (t1 + u * (t2 - t1))[..., None]  # (segments, samples, 1)
    t0, t1, t2, t3 = 0.0, t1[:, None], t2[:, None], t3[:, None]
    P0, P1, P2, P3 = (q[:, None, :] for q in (p0, p1, p2, p3))
    a1 = ((t1 - t) * P0 + (t - t0) * P1) / (t1 - t0)
    a2 = ((t2 - t) * P1 + (t - t1) * P2) / (t2 - t1)
    a3 = ((t3 - t) * P2 + (t - t2) * P3) / (t3 - t2)
    b1 = ((t2 - t) * a1 + (t - t0) * a2) / (t2 - t0)
    b2 = ((t3 - t) * a2 + (t - t1) * a3) / (t3 - t1)
    c = ((t2 - t) * b1 + (t - t1) * b2) / (t2 - t1)
    dense = c.reshape(-1, p.shape[1])
    return np.vstack([dense, p[:1] if closed else p[-1:]])


def curve_to_points(spline: BSpline, points: np.ndarray, closed: bool = False, per_span: int = 16,
                    extra: np.ndarray | None = None, model: np.ndarray | None = None,
                    with_samples: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Distance of curve samples to the data (their polyline, or ``model``: a dense polyline such as
    :func:`data_model`; closed data get their closing segment).

    Samples: ``per_span`` per knot span plus the parameters ``extra`` (e.g. midpoints between the data's foot
    points, where an excursion between two neighbouring data points would show). Returns one distance per sample
    (and the samples, with ``with_samples``).
    """
    t = spline.t
    knots = np.unique(t[(t >= 0.0) & (t <= 1.0)])
    u = (knots[:-1, None] + np.diff(knots)[:, None] * np.linspace(0.0, 1.0, per_span, endpoint=False)[None]).ravel()
    u = np.concatenate([u, [1.0], [] if extra is None else np.asarray(extra, dtype=np.float64).ravel()])
    p = np.asarray(points, dtype=np.float64)
    poly = model if model is not None else (np.vstack([p, p[:1]]) if closed else p)
    samples = spline(np.clip(u, 0.0, 1.0))
    dist = point_to_polyline(samples, poly)
    return (dist, samples) if with_samples else dist


def two_sided(spline: BSpline, points: np.ndarray, closed: bool = False, per_span: int = 32,
              corners: np.ndarray | None = None, dense: int = 2048, with_samples: bool = False) -> tuple:
    """``(data -> curve, curve -> data)`` distances: each data point to the curve, and curve samples (``per_span``
    per knot span) to the data's local model (:func:`data_model`; the plain polyline above 20 000 points).
    ``with_samples``: the curve samples as a third element."""
    p = np.asarray(points, dtype=np.float64)
    spans = len(np.unique(spline.t[(spline.t >= 0) & (spline.t <= 1)]))
    there = point_to_spline(spline, p, periodic=closed, dense=max(dense, 16 * spans),
                            seeds=6 if len(p) < 100_000 else 2)
    model = data_model(p, closed, corners, per_segment=8 if len(p) <= 20_000 else 1)
    back = curve_to_points(spline, p, closed, per_span, model=model, with_samples=with_samples)
    return (there, *back) if with_samples else (there, back)


def _segment_distance(p: np.ndarray, a: np.ndarray, ab: np.ndarray, len2: np.ndarray) -> np.ndarray:
    """Distance of ``p[i]`` to the segment ``a[i] + s ab[i]``, ``s`` in [0, 1] (broadcasts over leading axes)."""
    ap = p - a
    s = np.divide((ap * ab).sum(-1), len2, out=np.zeros(np.broadcast_shapes(ap.shape[:-1], len2.shape)),
                  where=len2 > 0.0)
    s = np.clip(s, 0.0, 1.0)
    return np.linalg.norm(ap - s[..., None] * ab, axis=-1)


def point_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Exact distance of each point to an open polyline (its segments, end points included)."""
    p = _as_points(points, "points")
    q = _as_points(polyline, "polyline", p.shape[1])
    if len(q) == 0:
        raise InputError("polyline needs at least one point")
    if len(q) == 1:
        return np.linalg.norm(p - q[0], axis=1)
    a, ab = q[:-1], np.diff(q, axis=0)
    len2 = np.einsum("ij,ij->i", ab, ab)
    n_seg = len(a)
    if len(p) * n_seg <= _DENSE_PAIRS:
        return _segment_distance(p[:, None, :], a[None], ab[None], len2[None]).min(axis=1)
    # Prune with a KD-tree on midpoints of pieces no longer than the mean segment (at most 2 * n_seg
    # pieces): a segment can beat the upper bound ``ub`` only if one of its pieces has its midpoint
    # within ``ub + longest piece half-length`` of the point.
    length = np.sqrt(len2)
    mean = length.mean()
    n_pieces = np.maximum(1, np.ceil(length / mean).astype(np.int64)) if mean > 0.0 else np.ones(n_seg, np.int64)
    parent = np.repeat(np.arange(n_seg), n_pieces)
    first = np.repeat(np.cumsum(n_pieces) - n_pieces, n_pieces)
    frac = (np.arange(len(parent)) - first + 0.5) / n_pieces[parent]
    tree = cKDTree(a[parent] + frac[:, None] * ab[parent])
    _, near = tree.query(p)
    near = parent[near]
    ub = _segment_distance(p, a[near], ab[near], len2[near])
    radius = ub + 0.5 * (length / n_pieces).max() * (1.0 + 1e-9) + 1e-12
    counts = tree.query_ball_point(p, radius, return_length=True)
    out = ub.copy()
    # Candidate pairs are gathered in blocks of consecutive points holding about _PAIR_BLOCK pairs each.
    block = np.searchsorted(np.cumsum(counts), np.arange(_PAIR_BLOCK, counts.sum() + _PAIR_BLOCK, _PAIR_BLOCK))
    bounds = np.unique(np.concatenate([[0], np.minimum(block + 1, len(p)), [len(p)]]))
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        c = counts[lo:hi]
        lists = tree.query_ball_point(p[lo:hi], radius[lo:hi], return_sorted=False)
        pi = np.repeat(np.arange(lo, hi), c)
        si = parent[np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=int(c.sum()))]
        d = _segment_distance(p[pi], a[si], ab[si], len2[si])
        has = c > 0
        starts = (np.cumsum(c) - c)[has]
        out[lo:hi][has] = np.minimum(out[lo:hi][has], np.minimum.reduceat(d, starts))
    return out
