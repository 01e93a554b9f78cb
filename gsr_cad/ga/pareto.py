"""Non-dominated sorting for the accuracy/complexity front (minimised objectives, no geometry).

With the optional ``moo`` extra (pymoo, the well-kept multi-objective library) its fast non-dominated sort is
used; without it, a vectorised pairwise test gives the same set.
"""

from __future__ import annotations

import numpy as np

try:
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting
except ImportError:  # the optional extra is not installed
    NonDominatedSorting = None


def non_dominated(objectives: np.ndarray, use_pymoo: bool = True) -> np.ndarray:
    """Sorted indices of the rows of ``objectives`` (``(n, k)``, all minimised) that no other row dominates (no
    worse in every objective and better in one); rows with a non-finite objective are left out."""
    F = np.asarray(objectives, dtype=np.float64)
    if F.ndim != 2:
        raise ValueError("objectives must be an (n, k) array")
    finite = np.flatnonzero(np.all(np.isfinite(F), axis=1))
    if finite.size == 0:
        return finite
    G = F[finite]
    if use_pymoo and NonDominatedSorting is not None:
        keep = np.asarray(NonDominatedSorting().do(G, only_non_dominated_front=True), dtype=np.int64)
    else:
        no_worse = np.all(G[:, None, :] <= G[None, :, :], axis=2)  # [i, j]: i no worse than j everywhere
        better = np.any(G[:, None, :] < G[None, :, :], axis=2)
        keep = np.flatnonzero(~np.any(no_worse & better, axis=0))
    return np.sort(finite[keep])


def has_pymoo() -> bool:
    """Whether the optional pymoo extra is installed."""
    return NonDominatedSorting is not None


def fronts(objectives: np.ndarray) -> list[np.ndarray]:
    """The rows of ``objectives`` by non-dominated rank: the non-dominated rows first, then those only they
    dominate, and so on (pymoo's sort when installed); rows with a non-finite objective form the last front."""
    F = np.asarray(objectives, dtype=np.float64)
    finite = np.all(np.isfinite(F), axis=1)
    rest = np.flatnonzero(finite)
    out: list[np.ndarray] = []
    if rest.size and NonDominatedSorting is not None:
        out = [np.sort(rest[np.asarray(f, dtype=np.int64)]) for f in NonDominatedSorting().do(F[rest])]
    else:
        while rest.size:
            keep = non_dominated(F[rest], use_pymoo=False)
            out.append(rest[keep])
            rest = np.delete(rest, keep)
    if not finite.all():
        out.append(np.flatnonzero(~finite))
    return out


def crowding(objectives: np.ndarray) -> np.ndarray:
    """NSGA-II's crowding distance of each row within its front: the sum over objectives of the gap between
    its neighbours (objectives scaled by their range), infinite at each objective's extremes."""
    F = np.asarray(objectives, dtype=np.float64)
    n, k = F.shape
    out = np.zeros(n)
    if n <= 2:
        return np.full(n, np.inf)
    for j in range(k):
        order = np.argsort(F[:, j], kind="stable")
        col = F[order, j]
        span = col[-1] - col[0]
        out[order[[0, -1]]] = np.inf
        if span > 0 and np.isfinite(span):
            out[order[1:-1]] += (col[2:] - col[:-2]) / span
    return out


def nsga2_order(objectives: np.ndarray) -> np.ndarray:
    """Indices of the rows in NSGA-II's survival order: by non-dominated rank, within a rank the least
    crowded first (ties by index: deterministic)."""
    F = np.asarray(objectives, dtype=np.float64)
    order: list[int] = []
    for front in fronts(F):
        part = F[front]
        dist = crowding(part) if np.all(np.isfinite(part)) else np.zeros(len(front))
        order += [int(front[i]) for i in np.lexsort((front, -dist))]
    return np.array(order, dtype=np.int64)
