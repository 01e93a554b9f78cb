"""Huge inputs: the surface search sees a bounded sample of a large cloud, the reported distances every point
(exactly, in bounded chunks). The timed figures are in benchmarks/huge.py, not here."""

from __future__ import annotations

import numpy as np
import pytest

from gsr_cad.geometry.limit_surface import LimitSurface
from gsr_cad.reconstruct import surface as surface_mod
from gsr_cad.reconstruct.inputs import SurfaceTarget, surface_target
from gsr_cad.reconstruct.surface import data_distances, reconstruct_surface, surface_metrics
from gsr_cad.reconstruct.surface_samples import SURFACE_SAMPLES


@pytest.fixture(scope="module")
def truth():
    return SURFACE_SAMPLES["inset_extrude"]().truth_control


def _noisy_cloud(control, n: int, seed: int) -> np.ndarray:
    """``n`` points on the limit surface moved off it by up to 2 % of its size (some far, most near)."""
    rng = np.random.default_rng(seed)
    points = LimitSurface.of(control).random_points(n, seed)
    return points + rng.normal(size=points.shape) * rng.exponential(2e-3, size=(n, 1))


@pytest.mark.parametrize("chunk", [333, 5000])
def test_chunked_distances_equal_the_full_search_on_every_point(truth, chunk):
    surface = LimitSurface.of(truth.with_vertices(truth.vertices * 1.02))
    points = _noisy_cloud(truth, 3000, 3)
    reference = surface.closest(points).distance
    got = data_distances(surface, points, seeds=400, chunk=chunk)
    assert got.shape == (3000,)
    np.testing.assert_allclose(got, reference, rtol=1e-9, atol=1e-12)
    assert got.max() == reference.max()


def test_a_huge_cloud_keeps_no_whole_cloud_radius(truth):
    """The cloud direction needs the sampling radius of the points nearest to the surface samples only."""
    target = SurfaceTarget(_noisy_cloud(truth, 4000, 5), None, "cloud")
    idx = np.arange(0, 4000, 7)
    partial = target.radius_at(idx)
    assert "sampling_radius" not in target.__dict__
    np.testing.assert_array_equal(partial, target.sampling_radius[idx])


def test_a_subsampled_search_reports_distances_over_every_point(truth, monkeypatch):
    monkeypatch.setattr(surface_mod, "SEARCH_POINTS", 1500)
    points = LimitSurface.of(truth).random_points(6000, 11)
    search = SurfaceTarget(points, None, "cloud").subsampled(1500, surface_mod._TARGET_SEED)
    seen = {tuple(p) for p in search.points.tolist()}
    outlier = next(i for i in range(len(points)) if tuple(points[i]) not in seen)
    diag = float(np.linalg.norm(np.ptp(points, axis=0)))
    away = points[outlier] - points.mean(axis=0)
    points[outlier] += 0.05 * diag * away / np.linalg.norm(away)
    target = surface_target(points, "cloud")
    result = reconstruct_surface(target, seed=2, generations=1, population=6, initial_population=6, n_parents=2, n_perturb=2,
                                 simplify_history=False, final_polish_rounds=1, polish_every=0)
    m = result.metrics
    assert m["n_data_samples"] == len(points) == 6000
    assert m["n_search_points"] == 1500
    config = surface_mod.SurfaceConfig.preset("default")
    on_search = surface_metrics(result.control_mesh, surface_target(search.points, "search"), config)
    # the largest distance is the outlier's, which the search never saw
    distances = data_distances(LimitSurface.of(result.control_mesh), target.points)
    assert int(np.argmax(distances)) == outlier
    assert m["data_to_fit_max"] == pytest.approx(distances[outlier] / target.diagonal, rel=1e-9)
    assert m["data_to_fit_max"] > on_search["data_to_fit_max"]
    assert m["data_to_fit_mean"] == pytest.approx(distances.mean() / target.diagonal, rel=1e-9)


def test_a_huge_curve_report_draws_an_ordered_bounded_subset():
    from gsr_cad.cli._common import REPORT_POINTS, report_points

    points = np.stack([np.arange(250_001.0), np.sin(np.arange(250_001.0))], axis=1)
    drawn = report_points(points)
    assert len(drawn) == REPORT_POINTS
    assert np.array_equal(drawn[0], points[0]) and np.array_equal(drawn[-1], points[-1])
    assert np.all(np.diff(drawn[:, 0]) > 0)  # curve order kept
    small = points[:500]
    assert report_points(small) is small
