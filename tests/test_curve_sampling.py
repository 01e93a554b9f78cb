"""The sampling test behind noisy open curves' counts: evenly spaced samples (up to a smooth warp) get the count
their spacing supports; unevenly thinned samples keep the free model's; free end points under noise."""

import numpy as np
import pytest

from gsr_cad import genome as genome_mod
from gsr_cad.geometry import bspline
from gsr_cad.geometry.curvefit import CurveFit, fit_curve, tangent_refine, warped_fit
from gsr_cad.ops.curve import template_from_config
from gsr_cad.reconstruct.curve import reconstruct_curve
from gsr_cad.reconstruct.samples import get_sample

SIGMA = 0.007  # of the diagonal, as in the paper's Figure 4 and the degraded benchmark


def _noisy(points: np.ndarray, seed) -> np.ndarray:
    diag = np.linalg.norm(np.ptp(points, axis=0))
    return points + np.random.default_rng(seed).normal(0.0, SIGMA * diag, points.shape)


def _truth(name: str):
    base = get_sample(name)
    return base, bspline.make_spline(np.asarray(base.truth_ctrl, dtype=np.float64), 3, False)


def _replays(result) -> None:
    template = template_from_config(result.config)
    np.testing.assert_allclose(genome_mod.replay(template, result.genome).points, result.control_points,
                               rtol=0, atol=1e-12)


def test_evenly_spaced_noisy_12_point_curve_gets_its_count():
    """The free model alone returns 9 here (12 and 9 points are within the likelihood ratio's reach)."""
    base = get_sample("bspline_12")
    pts = _noisy(np.asarray(base.points), [0, sum(map(ord, base.name)), 5])  # the degraded benchmark's seed 0
    result = reconstruct_curve(pts, seed=0)
    sampling = result.metrics["sampling"]
    assert sampling["evenly_spaced"] and sampling["p_value"] >= 0.01 and sampling["warp_terms"] == 0
    assert 11 <= result.metrics["n_control_points"] <= 13
    assert sampling["free_model_count"] < 11
    ctrl = result.control_points
    assert np.linalg.norm(ctrl[0] - pts[0]) > 0 and np.linalg.norm(ctrl[-1] - pts[-1]) > 0  # the ends are free
    _replays(result)


@pytest.mark.parametrize("seed", [0, 1])
def test_squared_parameter_sampling_is_not_over_counted(seed):
    """A 7-point curve sampled at u = s^2: the evenly spaced model needs 16 points, the free model 9-11 (its
    fit of 7 points sticks in a local minimum); the one-term warp gets the true count."""
    _, spline = _truth("bspline_07")
    clean = spline(np.linspace(0.0, 1.0, 200) ** 2)
    result = reconstruct_curve(_noisy(clean, 100 + seed), seed=seed)
    assert 6 <= result.metrics["n_control_points"] <= 8
    assert result.metrics["sampling"]["warp_terms"] >= 1
    _replays(result)


def test_squared_parameter_sampling_clean_is_exact():
    _, spline = _truth("bspline_07")
    result = reconstruct_curve(spline(np.linspace(0.0, 1.0, 200) ** 2), seed=0)
    assert result.metrics["n_control_points"] == 7
    assert result.metrics["data_to_fit_max"] < 1e-9
    assert "sampling" not in result.metrics  # exact data: nothing to decide


def test_randomly_thinned_samples_reject_even_spacing():
    """Half the samples removed at random: the index no longer follows the parameter, no smooth warp fits, the
    test rejects and the free model's count stands (the evenly spaced model would take 11-16 points)."""
    _, spline = _truth("bspline_07")
    rng = np.random.default_rng(101)
    keep = np.sort(np.concatenate([[0, 199], rng.choice(np.arange(1, 199), 98, replace=False)]))
    pts = _noisy(spline(np.linspace(0.0, 1.0, 200))[keep], 7)
    result = reconstruct_curve(pts, seed=1)
    assert result.metrics["sampling"]["evenly_spaced"] is False
    assert result.metrics["sampling"]["p_value"] < 0.01
    assert 6 <= result.metrics["n_control_points"] <= 8
    _replays(result)


def test_warped_fit_recovers_a_squared_warp_exactly():
    _, spline = _truth("bspline_07")
    s = np.linspace(0.0, 1.0, 150)
    pts = spline(s ** 2)
    fit, coef = warped_fit(pts, 7, 1, starts=(np.array([-0.5]),))  # s^2 = s - s (1 - s): coefficient -1
    assert fit.rms < 1e-9 and abs(coef[0] + 1.0) < 1e-6
    plain, _ = warped_fit(spline(s), 7, 0)  # no terms: the paper's evenly spaced correspondence
    assert plain.rms < 1e-9
    assert warped_fit(pts, 7, 0)[0].rms > 1e-3  # the spacing matters


def test_free_ends_fit_noisy_ends_and_keep_clean_exact():
    _, spline = _truth("bspline_05")
    clean = spline(np.linspace(0.0, 1.0, 120))
    pts = _noisy(clean, 3)
    pinned = tangent_refine(pts, fit_curve(pts, 5, 3, iterations=60), 3)
    free = tangent_refine(pts, pinned, 3, free_ends=True)
    assert free.rms < pinned.rms
    assert free.params[0] == 0.0 and free.params[-1] == 1.0  # the end samples stay at the curve's ends
    assert free.distances[0] == pytest.approx(np.linalg.norm(free.ctrl[0] - pts[0]))
    assert np.linalg.norm(free.ctrl[0] - pts[0]) > 0
    exact = fit_curve(clean, 5, 3, iterations=60, joint=True)
    again = tangent_refine(clean, CurveFit(exact.ctrl, exact.params, exact.distances), 3, free_ends=True)
    assert again.rms / np.linalg.norm(np.ptp(clean, axis=0)) < 1e-10


def test_model_error_is_not_taken_for_noise():
    """A smooth curve that is not a B-spline leaves a residual hundreds of times the data's own noise estimate:
    the sampling test does not run."""
    from gsr_cad.reconstruct.curve_model import _noise_variance

    rng = np.random.default_rng(4)
    white = rng.normal(0.0, 0.3, (4000, 2))
    assert _noise_variance(white) == pytest.approx(0.09, rel=0.1)  # unit variance on white noise
    result = reconstruct_curve(get_sample("sine_arc").points, seed=0)
    assert "sampling" not in result.metrics
