"""Non-dominated sorting of the accuracy/complexity front: pymoo's and the numpy fallback agree."""

from __future__ import annotations

import numpy as np
import pytest

from gsr_cad.ga.pareto import has_pymoo, non_dominated


def _dominated(F: np.ndarray, i: int) -> bool:
    return bool(np.any(np.all(F <= F[i], axis=1) & np.any(F < F[i], axis=1)))


@pytest.mark.parametrize("seed", range(5))
def test_the_front_is_exactly_the_non_dominated_rows(seed):
    rng = np.random.default_rng(seed)
    F = np.c_[rng.integers(8, 60, 80), rng.random(80)]  # (control vertices, distance): ties in the first
    F[3, 1] = np.inf  # a genome that did not replay
    keep = non_dominated(F, use_pymoo=False)
    assert 3 not in keep
    assert set(keep) == {i for i in range(len(F)) if np.isfinite(F[i]).all() and not _dominated(F, i)}
    if has_pymoo():
        assert np.array_equal(non_dominated(F), keep)


def test_empty_and_bad_input():
    assert non_dominated(np.zeros((0, 2))).size == 0
    with pytest.raises(ValueError):
        non_dominated(np.zeros(3))
