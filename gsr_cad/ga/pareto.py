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
