"""The real-data benchmark names a target of several disjoint pieces."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from gsr_cad.reconstruct.inputs import SurfaceTarget

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from real_data import parts  # noqa: E402


def _tetra(offset: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float) + offset
    return v, np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])


def test_disjoint_pieces_are_counted():
    (a, fa), (b, fb) = _tetra(0.0), _tetra(5.0)
    assert parts(SurfaceTarget(a, fa, "one")) == 1
    two = SurfaceTarget(np.vstack([a, b]), np.vstack([fa, fb + 4]), "two")
    assert parts(two) == 2
