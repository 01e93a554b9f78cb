"""Curve distances against brute force: dense sampling refined by a bounded scalar minimiser, explicit segment loops."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline
from scipy.optimize import minimize_scalar

from gsr_cad.errors import InputError
from gsr_cad.geometry import bspline as B
from gsr_cad.geometry import distance as D

DENSE = 100_001


def wiggly(seed, n=9, dim=2):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(size=(n, dim)), axis=0)


def brute_force_distance(ctrl, points, k):
    """Nearest of DENSE samples, then a bounded 1-D minimisation of |C(t) - p| around it."""
    spline = BSpline(B.clamped_uniform_knots(len(ctrl), k), ctrl, k)
    x = np.linspace(0, 1, DENSE)
    samples = spline(x)
    out, params = [], []
    h = 1.0 / (DENSE - 1)
    for p in points:
        d2 = ((samples - p) ** 2).sum(axis=1)
        i = int(np.argmin(d2))
        res = minimize_scalar(lambda t: float(np.linalg.norm(spline(t) - p)), method="bounded",
                              bounds=(max(0.0, x[i] - h), min(1.0, x[i] + h)), options={"xatol": 1e-14})
        best = min(math.sqrt(d2[i]), res.fun)
        out.append(best)
        params.append(res.x if res.fun <= math.sqrt(d2[i]) else x[i])
    return np.array(out), np.array(params)


def test_index_wise_is_per_row_euclidean():
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 2)), rng.normal(size=(50, 2))
    expected = [math.dist(p, q) for p, q in zip(a, b)]
    np.testing.assert_allclose(D.index_wise(a, b), expected, rtol=1e-15, atol=0)
    with pytest.raises(InputError):
        D.index_wise(a, b[:-1])


def test_chord_length_params():
    pts = np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 4.0], [3.0, 9.0], [3.0, 19.0]])
    np.testing.assert_allclose(D.chord_length_params(pts), [0.0, 0.25, 0.25, 0.5, 1.0], rtol=0, atol=1e-15)
    t = D.chord_length_params(wiggly(1, 30))
    assert t[0] == 0.0 and t[-1] == 1.0 and np.all(np.diff(t) > 0)
    with pytest.raises(InputError):
        D.chord_length_params(np.ones((4, 2)))
    with pytest.raises(InputError):
        D.chord_length_params(np.ones((1, 2)))


@pytest.mark.parametrize("k", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_point_to_curve_matches_brute_force(k, seed):
    ctrl = wiggly(seed)
    rng = np.random.default_rng(seed + 10)
    on = B.evaluate(ctrl, rng.random(20), k)
    near = on + rng.normal(scale=0.1, size=on.shape)
    far = rng.uniform(ctrl.min(0) - 2, ctrl.max(0) + 2, size=(40, 2))
    pts = np.concatenate([near, far, ctrl[[0, -1]] + [[-1.0, 0.5], [0.7, 0.2]]])
    ours = D.point_to_curve(ctrl, pts, degree=k)
    oracle, _ = brute_force_distance(ctrl, pts, k)
    np.testing.assert_allclose(ours, oracle, rtol=0, atol=1e-8)
    np.testing.assert_allclose(D.point_to_curve(ctrl, on, degree=k), 0.0, rtol=0, atol=1e-9)


@pytest.mark.parametrize("k", [2, 3])
def test_foot_points_converge_to_orthogonal_feet_from_nearby_seeds(k):
    ctrl = wiggly(5)
    rng = np.random.default_rng(6)
    t_true = rng.uniform(0.05, 0.95, 60)
    pts = B.evaluate(ctrl, t_true, k) + rng.normal(scale=0.05, size=(60, 2))
    oracle, t_oracle = brute_force_distance(ctrl, pts, k)
    t0 = np.clip(t_oracle + rng.uniform(-0.01, 0.01, 60), 0, 1)
    t, d = D.foot_points(ctrl, pts, t0, degree=k, iterations=6)
    np.testing.assert_allclose(d, oracle, rtol=0, atol=1e-9)
    spline = BSpline(B.clamped_uniform_knots(len(ctrl), k), ctrl, k)
    np.testing.assert_allclose(d, np.linalg.norm(spline(t) - pts, axis=1), rtol=0, atol=1e-12)
    inner = (t > 0) & (t < 1)
    tangent = spline.derivative()(t)
    # Newton's parameter error: the residual's tangential part over the squared speed.
    param_error = np.einsum("ij,ij->i", spline(t) - pts, tangent) / np.einsum("ij,ij->i", tangent, tangent)
    assert np.abs(param_error[inner]).max() < 1e-8


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 4), iterations=st.integers(0, 6))
def test_foot_points_never_increase_the_distance(seed, k, iterations):
    rng = np.random.default_rng(seed)
    ctrl = rng.normal(size=(k + 1 + int(rng.integers(0, 8)), 2))
    pts = rng.normal(size=(30, 2)) * 2
    t0 = rng.random(30)
    start = np.linalg.norm(B.evaluate(ctrl, t0, k) - pts, axis=1)
    t, d = D.foot_points(ctrl, pts, t0, degree=k, iterations=iterations)
    assert np.all((t >= 0) & (t <= 1))
    assert np.all(d <= start + 1e-12)
    np.testing.assert_allclose(d, np.linalg.norm(B.evaluate(ctrl, t, k) - pts, axis=1), rtol=0, atol=1e-12)


def brute_polyline(points, polyline):
    """Distance to every segment by the textbook projection formula, one segment at a time."""
    best = np.full(len(points), np.inf)
    for a, b in zip(polyline[:-1], polyline[1:]):
        ab = b - a
        denom = ab @ ab
        s = np.zeros(len(points)) if denom == 0 else np.clip((points - a) @ ab / denom, 0, 1)
        best = np.minimum(best, np.linalg.norm(points - (a + s[:, None] * ab), axis=1))
    return best


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_pts=st.integers(0, 60), n_poly=st.integers(2, 40), dim=st.integers(2, 3))
def test_point_to_polyline_small_cases(seed, n_pts, n_poly, dim):
    rng = np.random.default_rng(seed)
    poly = rng.normal(size=(n_poly, dim))
    poly[rng.random(n_poly) < 0.2] = poly[0]  # repeated vertices give zero-length segments
    pts = rng.normal(size=(n_pts, dim)) * 1.5
    np.testing.assert_allclose(D.point_to_polyline(pts, poly), brute_polyline(pts, poly), rtol=0, atol=1e-12)


@pytest.mark.parametrize("layout", ["walk", "one_long_segment", "dense_then_far"])
def test_point_to_polyline_pruned_path_is_exact(layout):
    rng = np.random.default_rng(4)
    if layout == "walk":
        poly = np.cumsum(rng.normal(size=(3000, 2)), axis=0)
    elif layout == "one_long_segment":
        poly = np.concatenate([np.cumsum(rng.normal(scale=0.01, size=(2000, 2)), axis=0), [[50.0, 50.0]]])
    else:
        poly = np.concatenate([np.c_[np.linspace(0, 1, 2000), np.zeros(2000)], [[100.0, 0.0], [100.0, 3.0]]])
    lo, hi = poly.min(0) - 1, poly.max(0) + 1
    pts = np.concatenate([rng.uniform(lo, hi, size=(400, 2)), poly[::37], (poly[:-1:53] + poly[1::53]) / 2])
    assert len(pts) * (len(poly) - 1) > D._DENSE_PAIRS
    ours = D.point_to_polyline(pts, poly)
    np.testing.assert_allclose(ours, brute_polyline(pts, poly), rtol=0, atol=1e-12)
    assert np.all(ours[400:] < 1e-12)


def test_single_point_polyline_and_bad_input():
    pts = np.array([[3.0, 4.0], [0.0, 0.0]])
    np.testing.assert_allclose(D.point_to_polyline(pts, np.zeros((1, 2))), [5.0, 0.0])
    with pytest.raises(InputError):
        D.point_to_polyline(pts, np.zeros((3, 3)))
    with pytest.raises(InputError):
        D.point_to_polyline(pts, np.zeros((0, 2)))
    with pytest.raises(InputError):
        D.point_to_curve(wiggly(0), np.array([[np.nan, 0.0]]))
    with pytest.raises(InputError):
        D.foot_points(wiggly(0), pts, np.array([0.5]))
    with pytest.raises(InputError):
        D.point_to_curve(wiggly(0), pts, dense=1)


def test_point_to_curve_near_a_self_approach_finds_the_true_branch():
    """A curve that passes close to itself: the nearest dense sample alone seeds the wrong foot point."""
    ctrl = np.array([[0, 0], [12.56996535, -0.41763473], [12.76558906, 2.50161236], [5.02490944, 2.4262604],
                     [1.68545872, 3.60382531], [0, 0], [3.06873289, 0.25845934], [8.27865888, 1.84045837],
                     [0.42336002, 12], [12, 0.42336002]])
    point = np.array([[10.5349, 2.00684]])
    brute = D.point_to_curve(ctrl, point, dense=200_000, seeds=12)
    assert D.point_to_curve(ctrl, point)[0] == pytest.approx(brute[0], abs=1e-9)
    assert brute[0] == pytest.approx(0.0890358, abs=1e-6)
