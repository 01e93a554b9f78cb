"""Looking at curve data before fitting: point order, closure, corners and subsampling (numpy/scipy only)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError

ORDER_RATIO = 4.0  # path length over summed nearest-neighbour distances above which data count as unordered
JUMP_FACTOR = 8.0  # a step this many times the median step (and over 2 % of the diagonal) is a jump
MAX_ORDERED = 200_000  # more unordered points than this are refused rather than ordered


def _steps(p: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(p, axis=0), axis=1)


def order_score(points: np.ndarray) -> tuple[float, float]:
    """``(path length / summed nearest-neighbour distances, fraction of jumps)`` of a point sequence.

    Ordered samples of a curve score about 1-2 and few jumps; shuffled ones score in the tens or more.
    """
    p = np.asarray(points, dtype=np.float64)
    steps = _steps(p)
    nn = cKDTree(p).query(p, k=2)[0][:, 1]
    diag = float(np.linalg.norm(np.ptp(p, axis=0)))
    jumps = (steps > JUMP_FACTOR * np.median(steps)) & (steps > 0.02 * diag)
    return float(steps.sum() / max(nn.sum(), 1e-300)), float(jumps.mean())


def is_unordered(points: np.ndarray) -> bool:
    """True when the sequence does not look like consecutive samples along a curve."""
    ratio, jumps = order_score(points)
    return ratio > ORDER_RATIO or jumps > 0.05


def _greedy_path(tree: cKDTree, p: np.ndarray, start: int) -> np.ndarray:
    m = len(p)
    visited = np.zeros(m, dtype=bool)
    order = np.empty(m, dtype=np.int64)
    cur = start
    for i in range(m):
        order[i] = cur
        visited[cur] = True
        if i == m - 1:
            break
        k = 8
        while True:
            _, idx = tree.query(p[cur], k=min(k, m))
            idx = np.atleast_1d(idx)
            free = idx[~visited[idx]]
            if free.size:
                cur = int(free[0])
                break
            if k >= m:
                raise InputError("nearest-neighbour ordering failed")  # pragma: no cover - all visited
            k *= 4
    return order


def spread(points: np.ndarray, k: int = 10) -> float:
    """Median over the points of how far their ``k`` nearest neighbours spread across the main direction
    (second over first principal variance): near 0 along a curve, near 1 in a 2D cloud."""
    p = np.asarray(points, dtype=np.float64)
    _, idx = cKDTree(p).query(p, k=min(k, len(p)))
    local = p[idx] - p[idx].mean(axis=1, keepdims=True)
    eig = np.linalg.eigvalsh(np.einsum("nki,nkj->nij", local, local))  # ascending
    return float(np.median(eig[:, -2] / np.maximum(eig[:, -1], 1e-300)))


def nearest_neighbour_order(points: np.ndarray) -> np.ndarray:
    """Indices ordering the points along a nearest-neighbour path (two sweeps: the second starts where the
    first ended, which is usually an end of an open curve); InputError when the points do not lie along a
    curve or the path still jumps."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) > MAX_ORDERED:
        raise InputError(f"the {len(p)} points are not in curve order and are too many to order "
                         f"(at most {MAX_ORDERED}); sort them along the curve first")
    if spread(p) > 0.25:
        raise InputError("the points are not in curve order and do not lie along one curve (they spread "
                         "like a cloud); sort them along the curve first")
    tree = cKDTree(p)
    far = int(np.argmax(np.linalg.norm(p - p.mean(axis=0), axis=1)))
    order = _greedy_path(tree, p, int(_greedy_path(tree, p, far)[-1]))
    steps = _steps(p[order])
    diag = float(np.linalg.norm(np.ptp(p, axis=0)))
    big = steps > max(JUMP_FACTOR * np.median(steps), 0.05 * diag)
    if np.count_nonzero(big) > 1 or is_unordered(p[order]):
        raise InputError("the points are not in curve order and no reliable nearest-neighbour order exists "
                         f"({np.count_nonzero(big)} jumps remain); sort them along the curve first")
    return order


def detect_closed(points: np.ndarray) -> bool:
    """True when the last point is about as close to the first as consecutive points are to each other."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) < 8:
        return False
    steps = _steps(p)
    gap = float(np.linalg.norm(p[-1] - p[0]))
    return gap <= 3.0 * float(np.median(steps)) and gap < 0.1 * float(steps.sum())


def _at_arc(p: np.ndarray, s: np.ndarray, where: np.ndarray, total: float, closed: bool) -> np.ndarray:
    if closed:
        s_ext = np.concatenate([s, [total]])
        p_ext = np.vstack([p, p[:1]])
        where = np.mod(where, total)
    else:
        s_ext, p_ext = s, p
    return np.column_stack([np.interp(where, s_ext, p_ext[:, d]) for d in range(p.shape[1])])


def _turning(p: np.ndarray, s: np.ndarray, total: float, h: float, closed: bool) -> np.ndarray:
    a = p - _at_arc(p, s, s - h, total, closed)
    b = _at_arc(p, s, s + h, total, closed) - p
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    cos = np.einsum("ij,ij->i", a, b) / np.maximum(na * nb, 1e-300)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def corner_candidates(points: np.ndarray, closed: bool, min_angle: float = 25.0,
                      with_angles: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Indices of points where the data turn sharply: C0 corners rather than tight smooth bends.

    The turning angle is measured between the chords to the curve points an arc length ``h`` before and after
    each point (``h`` a few sample spacings, at least 0.4 % of the length). A corner turns by at least
    ``min_angle`` degrees and keeps most of its angle at ``h / 2`` (a smooth bend halves it); one index (the
    sharpest) is kept per run of such points. ``with_angles``: also their turning angles (degrees).
    """
    p = np.asarray(points, dtype=np.float64)
    steps = _steps(np.vstack([p, p[:1]]) if closed else p)
    total = float(steps.sum())
    s = np.concatenate([[0.0], np.cumsum(steps)[:len(p) - 1]])
    h = max(4.0 * float(np.median(steps)), 0.004 * total)
    big = _turning(p, s, total, h, closed)
    small = _turning(p, s, total, 0.5 * h, closed)
    flag = (big >= min_angle) & (small >= 0.75 * big)
    if not closed:
        flag &= (s > h) & (s < total - h)
    idx = np.flatnonzero(flag)
    if idx.size == 0:
        idx = np.zeros(0, dtype=np.int64)
    # Split into runs of nearby flagged points (arc distance <= h), keep the sharpest of each run.
    gaps = np.diff(s[idx]) > h
    runs = [r for r in np.split(idx, np.flatnonzero(gaps) + 1) if r.size]
    if closed and len(runs) > 1 and s[runs[0][0]] + total - s[runs[-1][-1]] <= h:
        runs[0] = np.concatenate([runs.pop(), runs[0]])
    score = small + big
    out = np.array([int(r[np.argmax(score[r])]) for r in runs], dtype=np.int64)
    angle = np.minimum(big, small)
    # A corner also shows at the sampling scale: the polyline turns there (at the vertex or a neighbour, by at
    # least 0.4 of the angle), whereas a round nose sampled coarsely turns a little at every vertex.
    # Densely sampled data (many points per 0.05 % of the length) are judged at that length instead.
    kink = _vertex_turning(p, closed)
    fine = 0.0005 * total
    scale = _turning(p, s, total, fine, closed) if fine > 1.5 * float(np.median(steps)) else kink
    local = np.maximum(scale, np.maximum(np.roll(scale, 1), np.roll(scale, -1)))
    out = out[local[out] >= 0.4 * angle[out]]
    # Isolated kinks of the polyline itself (e.g. both ends of a short trailing edge, closer than h): a vertex
    # turning >= 60 deg with a neighbour turning less than a third of that (a pixel staircase turns at every step).
    before, after = np.roll(kink, 1), np.roll(kink, -1)
    isolated = (kink >= max(60.0, min_angle)) & (np.minimum(before, after) < kink / 3.0)
    if not closed:
        isolated[[0, -1]] = False
    extra = np.flatnonzero(isolated)
    if extra.size:
        near = np.abs(out[:, None] - extra[None, :]).min(axis=1) <= 2 if out.size else np.zeros(0, dtype=bool)
        out = np.concatenate([out[~near], extra])
        angle[extra] = np.maximum(angle[extra], kink[extra])
    out = np.unique(out)
    return (out, angle[out]) if with_angles else out


def _vertex_turning(p: np.ndarray, closed: bool) -> np.ndarray:
    """Turning angle (degrees) of the polyline at each vertex, from its immediate neighbours (ends: 0 if open)."""
    a = p - np.roll(p, 1, axis=0)
    b = np.roll(p, -1, axis=0) - p
    cos = np.einsum("ij,ij->i", a, b) / np.maximum(np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1), 1e-300)
    out = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    if not closed:
        out[[0, -1]] = 0.0
    return out


def subsample(points: np.ndarray, limit: int, keep: np.ndarray, closed: bool) -> np.ndarray:
    """Sorted indices of at most about ``limit`` points spread by index and by arc length, plus ``keep``."""
    m = len(points)
    if m <= limit:
        return np.arange(m)
    p = np.asarray(points, dtype=np.float64)
    steps = _steps(p)
    s = np.concatenate([[0.0], np.cumsum(steps)])
    by_index = np.round(np.linspace(0, m - 1, limit // 2)).astype(np.int64)
    by_arc = np.searchsorted(s, np.linspace(0.0, s[-1], limit // 2)).clip(0, m - 1)
    if np.count_nonzero(np.abs(np.diff(s[by_index]) - s[-1] / max(1, limit // 2 - 1)) > 0.5 * s[-1] / limit) < limit // 20:
        by_index = by_arc = np.searchsorted(s, np.linspace(0.0, s[-1], limit)).clip(0, m - 1)  # evenly spaced data
    keep = np.unique(np.concatenate([np.asarray(keep, dtype=np.int64), [0, m - 1]]))
    out = np.unique(np.concatenate([by_index, by_arc]))
    # The two spreads nearly coincide on evenly spaced data: of points closer than a quarter of the arc
    # spacing only the first is kept (near-duplicates only bend the data's local model), then ``keep``.
    gap = 0.25 * s[-1] / max(1, len(by_arc))
    spaced = [out[0]]
    for i in out[1:]:
        if s[i] - s[spaced[-1]] >= gap:
            spaced.append(i)
    return np.union1d(np.asarray(spaced, dtype=np.int64), keep)
