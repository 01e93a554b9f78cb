"""Time budgets: a run with ``max_seconds`` finishes within about that time, the refinement included."""

from __future__ import annotations

import time

import numpy as np
import pytest

from gsr_cad.geometry.polymesh import PolyMesh
from gsr_cad.geometry.subdivision import get_catmull_clark, limit_mesh
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.refine import Timing
from gsr_cad.reconstruct.surface import reconstruct_surface


def _lumpy(seed: int) -> PolyMesh:
    """A cube refined twice (98 control vertices), its vertices moved out at random: a lumpy shape whose
    cage the refinement grows towards for many levels."""
    v = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
    mesh = PolyMesh.from_faces(v, [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    for _ in range(2):
        mesh = get_catmull_clark(mesh, 1, "all").refine(mesh.vertices)
    rng = np.random.default_rng(seed)
    return mesh.with_vertices(mesh.vertices * (1.0 + 0.3 * rng.random((mesh.n_vertices, 1))))


def test_timing_predicts_from_the_largest_smaller_cages():
    t = Timing()
    assert t.predict("round", 100) == 0.0
    t.add("round", 10, 1.0)
    t.add("round", 40, 2.0)
    t.add("commit", 10, 1.0)
    assert t.predict("round", 5) == pytest.approx(1.3 * 1.0)  # smaller than any: the smallest's, as it is
    assert t.predict("round", 20) == pytest.approx(1.3 * 2.0)  # from 10, linearly
    assert t.predict("round", 80) == pytest.approx(1.3 * 6.0)  # the median of 10's (8) and 40's (4), linearly
    assert t.predict("commit", 30) == pytest.approx(1.3 * 9.0)  # commits grow as the square


def test_one_slow_commit_does_not_set_every_later_prediction():
    t = Timing()
    for n, seconds in ((360, 0.13), (388, 0.25), (416, 41.0)):  # bone: one commit of many staged moves
        t.add("commit", n, seconds)
    assert t.predict("commit", 452) < 1.0


@pytest.mark.parametrize("budget", [30.0])  # 20 s left no room for the refinement under a loaded CI
def test_a_budget_holds_on_a_mid_size_mesh_with_the_refinement_running(budget):
    target = surface_target(limit_mesh(_lumpy(4), 3), "lumpy")  # 12,288 triangles
    assert len(target.faces) > 10_000
    start = time.perf_counter()
    result = reconstruct_surface(target, seed=1, max_seconds=budget, refine_until=1e-7)
    seconds = time.perf_counter() - start
    assert result.metrics["refinement"], "the refinement did not run: the test would not exercise its deadline"
    assert seconds <= 2.0 * budget, f"{seconds:.0f} s for a budget of {budget:g} s"
