"""The real-data benchmark names a target of several disjoint pieces, and its FreeCAD parts are what it says."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.templates import target_genus

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from real_data import FREECAD_IDF, FREECAD_PARTS, freecad_parts, parts  # noqa: E402


def _tetra(offset: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float) + offset
    return v, np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])


def test_disjoint_pieces_are_counted():
    (a, fa), (b, fb) = _tetra(0.0), _tetra(5.0)
    assert parts(SurfaceTarget(a, fa, "one")) == 1
    two = SurfaceTarget(np.vstack([a, b]), np.vstack([fa, fb + 4]), "two")
    assert parts(two) == 2


@pytest.mark.skipif(not FREECAD_IDF.is_dir(), reason=f"no FreeCAD IDF library at {FREECAD_IDF} (apt install freecad)")
def test_the_freecad_parts_are_closed_genus_0_single_solids(tmp_path):
    pytest.importorskip("build123d", reason="the cad extra (build123d) tessellates the STEP parts")
    got = freecad_parts(tmp_path)
    assert [p.stem for p in got] == list(FREECAD_PARTS)
    for path in got:
        target = surface_target(path)
        assert parts(target) == 1 and target_genus(target) == (0, "euler"), path.name
        assert len(target.faces) >= 100, path.name  # tessellated curved faces, not just a box
