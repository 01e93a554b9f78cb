"""Roulette-wheel selection on costs (lower is better): weight = 1 / cost, as the paper's fitness.

Edge cases are defined, not left to floating point: an individual of cost 0 (or so small that 1 / cost
overflows) is certain to be chosen (ties share the certainty); inf, nan and negative costs weigh nothing
(the worst); when nothing has weight, the choice is uniform.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def roulette_weights(costs: Sequence[float] | np.ndarray) -> np.ndarray:
    """Normalised selection probabilities for ``costs`` (sums to 1)."""
    c = np.asarray(costs, dtype=float).reshape(-1)
    n = c.size
    if n == 0:
        raise ValueError("roulette selection needs at least one individual")
    usable = np.isfinite(c) & (c >= 0)
    if not usable.any():
        return np.full(n, 1.0 / n)
    certain = usable & (c < 1.0 / np.finfo(float).max)  # 0, or so small that 1 / cost overflows
    if certain.any():
        w = certain.astype(float)
    else:  # 1 / cost scaled by the lowest cost: each at most 1, and no sum of them overflows
        w = np.zeros(n)
        w[usable] = c[usable].min() / c[usable]
    return w / w.sum()


def roulette_select(costs: Sequence[float] | np.ndarray, k: int, rng: np.random.Generator,
                    replace: bool = True) -> np.ndarray:
    """Indices of ``k`` individuals drawn with probability proportional to 1 / cost.

    With ``replace=False`` the draw is sequential weighted sampling without replacement (each pick removes
    the individual from the wheel); individuals of zero weight come last, in random order, so ``k`` may be
    as large as the population.
    """
    p = roulette_weights(costs)
    n = p.size
    if k < 0 or (not replace and k > n):
        raise ValueError(f"cannot draw {k} of {n} individuals {'with' if replace else 'without'} replacement")
    if replace:
        return rng.choice(n, size=k, p=p)
    # Efraimidis-Spirakis: the k smallest keys E/w (E ~ Exp(1)) are a sequential weighted draw.
    with np.errstate(divide="ignore"):
        keys = rng.exponential(size=n) / p
    tiebreak = rng.random(n)
    order = np.lexsort((tiebreak, keys))
    return order[:k]
