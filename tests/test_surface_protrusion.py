"""Protrusion starts: a bump on one side of the target is found as an inset then an extrude of that face, at
any tessellation level, and a target without one gets no such start."""

from __future__ import annotations

import pytest

from gsr_cad.geometry.isomorphism import connectivity_hash
from gsr_cad.geometry.subdivision import limit_mesh
from gsr_cad.ops.rewrite import STRUCTURAL
from gsr_cad.reconstruct.config import SurfaceConfig
from gsr_cad.reconstruct.inputs import surface_target
from gsr_cad.reconstruct.surface import SurfaceProblem, box_template, reconstruct_surface
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES

SMALL = dict(population=8, initial_population=8, n_parents=3, max_children=2, n_perturb=2, n_newcomers=2,
             generations=2, refine=False)


def _problem(name: str, level: int, **config) -> SurfaceProblem:
    target = surface_target(limit_mesh(SURFACE_SAMPLES[name]().truth_control, level), f"{name}-L{level}")
    return SurfaceProblem(target, SurfaceConfig(**config), box_template(target))


def test_a_bump_gives_inset_then_extrude_starts_that_fit():
    problem = _problem("inset_extrude", 1)
    seeds = problem.protrusion_seeds()
    assert seeds
    assert [op.letter for op in seeds[0][:2]] == ["I", "E"]
    assert problem.evaluate(seeds[0], 0).cost < 1e-5  # fitted from there, the true structure fits


def test_no_bump_no_start_and_none_without_the_ops():
    assert _problem("extended", 1).protrusion_seeds() == []
    assert _problem("inset_extrude", 1, op_kinds="VELB").protrusion_seeds() == []


@pytest.mark.parametrize("level", [1, 3])
def test_the_inset_extrude_target_is_found_at_other_levels(level):
    sample = SURFACE_SAMPLES["inset_extrude"]()
    target = surface_target(limit_mesh(sample.truth_control, level), f"L{level}")
    result = reconstruct_surface(target, seed=1, **SMALL)
    structural = [c for c in result.metrics["ops"] if c in STRUCTURAL]
    assert structural == ["I", "E"]
    assert connectivity_hash(result.control_mesh) == connectivity_hash(sample.truth_control)
    assert result.metrics["data_to_fit_mean"] < 1e-5
