"""The curve search's fast paths (resumed trie walks, bracketed tolerance fits, the first population) and the
final check's segmentation of pieces that one uniform-knot span sequence cannot follow."""

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from gsr_cad.geometry import bspline
from gsr_cad.geometry.curvefit import fit_curve
from gsr_cad.reconstruct.config import CurveConfig
from gsr_cad.reconstruct.curve import CurveProblem, _common_prefix, reconstruct_curve
from gsr_cad.reconstruct.inputs import curve_target


def wavy(m=300):
    t = np.linspace(0.0, 1.0, m)
    return np.column_stack([t * 10.0, np.sin(6.0 * t) + 0.2 * np.sin(25.0 * t)])


def test_common_prefix():
    a, b = (1, 2, 3, 4), (1, 2, 9)
    assert _common_prefix(a, b) == 2
    assert _common_prefix(a, a[:3]) == 3
    assert _common_prefix((), a) == 0
    assert _common_prefix((5,), a) == 0


def test_resumed_walks_give_the_states_and_repairs_of_fresh_walks():
    pts = wavy()
    cfg = CurveConfig.preset("default")
    reused = CurveProblem(curve_target(pts), cfg)
    rng = np.random.default_rng(3)
    genomes = []
    for _ in range(30):  # growing prefixes, as a mutation builds them, and unrelated genomes in between
        genes: list = []
        for _ in range(int(rng.integers(3, 25))):
            genes.append(reused.random_gene(rng, tuple(genes)))
        genomes.append(tuple(genes))
    genomes += [g[:k] + genomes[0][k:] for g in genomes[1:6] for k in (1, 3)]
    for g in genomes:
        fresh = CurveProblem(curve_target(pts), cfg)
        assert np.array_equal(reused._state(g).points, fresh._state(g).points)
        assert reused._state(g).corners == fresh._state(g).corners
        r1, r2 = reused.repair(g, np.random.default_rng(0)), fresh.repair(g, np.random.default_rng(0))
        assert r1 == r2


def test_a_capped_add_is_dropped_as_before():
    pts = wavy(60)
    prob = CurveProblem(curve_target(pts), CurveConfig.preset("default", max_control_points=6))
    rng = np.random.default_rng(1)
    genes: list = []
    for _ in range(12):
        genes.append(prob.random_gene(rng, tuple(genes)))
    from gsr_cad.ops import curve as curve_ops
    adds = [curve_ops.AddPoint(1, tuple(float(v) for v in pts[k])) for k in (5, 10, 15, 20)]
    genome = tuple(adds) + tuple(genes)
    kept: list = []
    state = prob._walk(genome, kept)[0]
    assert state.n <= 6
    assert len([op for op in kept if isinstance(op, curve_ops.AddPoint)]) <= 2


def test_bracketed_fit_stops_once_within_its_goal_or_hopeless():
    ctrl = np.array([[0, 0], [1, 2], [3, 3], [4, 0], [6, 1], [7, 3]], dtype=float)
    pts = bspline.sample_uniform(ctrl, 200, 3) + 1e-4 * np.random.default_rng(0).normal(size=(200, 2))
    diag = float(np.linalg.norm(np.ptp(pts, axis=0)))
    full = fit_curve(pts, 12, 3, iterations=25)
    quick = fit_curve(pts, 12, 3, iterations=25, bracket=(0.01 * diag, 1.0 * diag))
    assert quick.distances.max() <= 0.01 * diag
    assert quick.rms >= full.rms * (1 - 1e-9)  # it stopped earlier: no better than the full refinement
    hopeless = fit_curve(pts, 4, 3, iterations=25, bracket=(1e-9 * diag, 1e-6 * diag))
    assert hopeless.distances.max() > 1e-6 * diag


def test_default_preset_first_population_and_paper_preset():
    assert CurveConfig.preset("default").initial_population == CurveConfig.preset("default").population
    assert CurveConfig.preset("paper").initial_population == 1000
    assert CurveConfig.preset("default", initial_population=500).initial_population == 500


def test_split_cuts_segments_inside_and_owners_share_joints():
    prob = CurveProblem(curve_target(wavy()), CurveConfig.preset("default"))
    m = prob.m
    assert prob._split((10, 50), {(10, 50): 30}) == (10, 30, 50)
    assert prob._split((10, 50), {(10, 50): 10}) == (10, 11, 50)  # kept one point inside
    assert prob._split((10, 50), {(10, 50): 50}) == (10, 49, 50)
    assert prob._split((10, 11), {(10, 11): 10}) == (10, 11)  # nothing inside: left whole
    keys = prob.model.segments((10, 50))
    first, last = prob._owners(keys)
    assert first[10] == 1 and last[10] == 0  # the joint belongs to both segments
    assert first[30] == last[30] == 1 and first[m - 1] == last[m - 1] == 2


def test_split_of_closed_segments_wraps():
    th = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    prob = CurveProblem(curve_target(np.column_stack([np.cos(th), np.sin(th)])), CurveConfig.preset("default"))
    assert prob.closed
    m = prob.m
    assert prob._split((), {(-1, -1): 17}) == (17,)
    assert prob._split((20, 150), {(150, 20 + m): 5}) == (5, 20, 150)  # the segment across the seam
    assert prob._split((20, 150), {(150, 20 + m): 150}) == (20, 150, 151)


@pytest.mark.slow
def test_dem_contour_meets_1e4_by_segmentation():
    pytest.importorskip("skimage")
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from real_curves import dem_contour

    pts = dem_contour()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = reconstruct_curve(pts, seed=0, max_distance=1e-4)
    assert result.metrics["tolerance_met"]
    assert len(result.control_points) < len(pts)


def test_tolerance_fits_are_bracketed_only_on_all_points(monkeypatch):
    import gsr_cad.reconstruct.curve_model as curve_model

    seen = []
    real = curve_model.fit_curve

    def spy(*args, **kwargs):
        seen.append(kwargs.get("bracket"))
        return real(*args, **kwargs)

    monkeypatch.setattr(curve_model, "fit_curve", spy)
    pts = wavy(1000)
    whole = CurveProblem(curve_target(pts), CurveConfig.preset("default", max_distance=1e-3))
    whole.model.fit((0, whole.m - 1), 12)
    assert seen[-1] is not None and seen[-1][0] < 1e-3 * whole.diag < seen[-1][1]
    sub = CurveProblem(curve_target(pts), CurveConfig.preset("default", max_distance=1e-3, search_points=200))
    assert sub.m < len(pts)
    sub.model.fit((0, sub.m - 1), 12)
    assert seen[-1] is None  # the final check refits a subsample's segments on all points: no early stop
    free = CurveProblem(curve_target(pts), CurveConfig.preset("default"))
    free.model.fit((0, free.m - 1), 12)
    assert seen[-1] is None
