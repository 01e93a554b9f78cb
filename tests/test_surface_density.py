"""A target tessellated at any level is the same surface: the true structure fits it to the same accuracy,
and the search finds the same structure."""

from __future__ import annotations

import pytest

from gsr_cad.geometry.isomorphism import connectivity_hash
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.surface import SurfaceProblem, reconstruct_surface, surface_metrics
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES


@pytest.mark.parametrize("level", [1, 2, 3, 4])
def test_the_true_cage_fits_a_target_at_any_level(level):
    s = SURFACE_SAMPLES["flattened_extended"]()
    target = surface_target(limit_mesh(s.truth_control, level), f"L{level}")
    config = SurfaceConfig()
    start = s.truth_control.with_vertices(s.truth_control.vertices * 1.03 + 0.01)
    problem = SurfaceProblem(target, config, start)
    fitted = start.with_vertices(problem.fit(start, 25, min_gain=0.999)[0])
    m = surface_metrics(fitted, target, config)
    assert m["data_to_fit_mean"] < 1e-4 and m["data_to_fit_max"] < 1e-3
    # the other direction measures the target's own chords, which shrink 4x per level
    assert m["fit_to_data_mean"] < 0.05 / 4 ** level


@pytest.mark.slow
@pytest.mark.parametrize("level", [1, 2, 3, 4])
def test_the_search_finds_the_same_structure_at_every_level(level):
    s = SURFACE_SAMPLES["extended"]()
    target = surface_target(limit_mesh(s.truth_control, level), f"L{level}")
    result = reconstruct_surface(target, seed=1, generations=30)
    assert connectivity_hash(result.control_mesh) == connectivity_hash(s.truth_control)
    assert result.metrics["data_to_fit_mean"] <= 1e-4
