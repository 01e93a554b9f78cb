"""Clamped uniform B-splines against scipy's de Boor evaluation (an independent code path from design_matrix)."""

from math import comb

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from gsr_cad.errors import InputError
from gsr_cad.geometry import bspline as B

CASES = [(k, n) for k in (2, 3) for n in range(k + 1, 22)]


def params(rng, m=60):
    return np.concatenate([[0.0, 1.0], rng.random(m), np.arange(1, 7) / 7])


def scipy_spline(ctrl, k):
    return BSpline(B.clamped_uniform_knots(len(ctrl), k), ctrl, k)


@pytest.mark.parametrize("k,n", CASES)
def test_knots_are_clamped_uniform(k, n):
    t = B.clamped_uniform_knots(n, k)
    assert t.shape == (n + k + 1,)
    assert np.all(t[: k + 1] == 0.0) and np.all(t[-k - 1:] == 1.0)
    inner = t[k:n + 1]
    np.testing.assert_allclose(np.diff(inner), 1.0 / (n - k), rtol=0, atol=1e-15)


@pytest.mark.parametrize("k,n", CASES)
def test_basis_and_evaluate_match_scipy(k, n):
    rng = np.random.default_rng(n * 10 + k)
    x = params(rng)
    ref_basis = scipy_spline(np.eye(n), k)(x)
    basis = B.basis_matrix(n, x, k)
    np.testing.assert_allclose(basis, ref_basis, rtol=0, atol=1e-12)
    np.testing.assert_allclose(basis.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    assert basis.min() >= 0.0
    ctrl = rng.normal(size=(n, 2)) * 10
    np.testing.assert_allclose(B.evaluate(ctrl, x, k), scipy_spline(ctrl, k)(x), rtol=0, atol=1e-11)
    ends = B.evaluate(ctrl, [0.0, 1.0], k)
    np.testing.assert_allclose(ends, ctrl[[0, -1]], rtol=0, atol=1e-12)


@pytest.mark.parametrize("k,n", CASES[::3])
def test_uniform_basis_is_cached_and_read_only(k, n):
    u = B.uniform_basis(n, 101, k)
    assert u is B.uniform_basis(n, 101, k)
    assert not u.flags.writeable
    with pytest.raises(ValueError):
        u[0, 0] = 2.0
    np.testing.assert_allclose(u, B.basis_matrix(n, np.linspace(0, 1, 101), k), rtol=0, atol=0)
    ctrl = np.random.default_rng(k).normal(size=(n, 3))
    np.testing.assert_allclose(B.sample_uniform(ctrl, 101, k), scipy_spline(ctrl, k)(np.linspace(0, 1, 101)),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("k,n", CASES)
def test_derivative_basis_matches_scipy_derivative(k, n):
    rng = np.random.default_rng(7 * n + k)
    x = params(rng)
    ctrl = rng.normal(size=(n, 2))
    spline = scipy_spline(ctrl, k)
    for order in range(1, k + 1):
        ref = spline.derivative(order)(x)
        ours = B.derivative_basis_matrix(n, x, k, order) @ ctrl
        np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-12 * max(1.0, np.abs(ref).max()))
    assert not np.any(B.derivative_basis_matrix(n, x, k, k + 1))
    np.testing.assert_array_equal(B.derivative_basis_matrix(n, x, k, 0), B.basis_matrix(n, x, k))


def bernstein(points, u):
    """Evaluate a Bezier piece ``(deg + 1, dim)`` at local parameters ``u`` in [0, 1]."""
    deg = len(points) - 1
    weights = np.stack([comb(deg, i) * u**i * (1 - u) ** (deg - i) for i in range(deg + 1)], axis=1)
    return weights @ points


@pytest.mark.parametrize("k,n", CASES + [(1, 2), (1, 5), (4, 9)])
def test_bezier_segments_reproduce_the_curve(k, n):
    rng = np.random.default_rng(n + 100 * k)
    ctrl = rng.normal(size=(n, 2)) * 5
    segs = B.bezier_segments(ctrl, k)
    n_spans = n - k
    assert segs.shape == (n_spans, k + 1, 2)
    spline = scipy_spline(ctrl, k)
    u = np.linspace(0.0, 1.0, 33)
    for j, piece in enumerate(segs):
        np.testing.assert_allclose(bernstein(piece, u), spline((j + u) / n_spans), rtol=0, atol=1e-11)
    np.testing.assert_allclose(segs[1:, 0], segs[:-1, -1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(segs[0, 0], ctrl[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(segs[-1, -1], ctrl[-1], rtol=0, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(k=st.integers(1, 4), extra=st.integers(0, 12), seed=st.integers(0, 2**32 - 1),
       shift=st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)))
def test_affine_invariance_and_scipy_agreement(k, extra, seed, shift):
    rng = np.random.default_rng(seed)
    ctrl = rng.normal(size=(k + 1 + extra, 2))
    x = rng.random(25)
    a = rng.normal(size=(2, 2))
    moved = B.evaluate(ctrl @ a + np.array(shift), x, k)
    np.testing.assert_allclose(moved, B.evaluate(ctrl, x, k) @ a + np.array(shift), rtol=0, atol=1e-9)
    np.testing.assert_allclose(B.evaluate(ctrl, x, k), scipy_spline(ctrl, k)(x), rtol=0, atol=1e-12)


@pytest.mark.parametrize("call", [
    lambda: B.clamped_uniform_knots(3, 3),
    lambda: B.clamped_uniform_knots(4, 0),
    lambda: B.clamped_uniform_knots(True, 1),
    lambda: B.basis_matrix(5, [0.5, 1.2]),
    lambda: B.basis_matrix(5, [np.nan]),
    lambda: B.uniform_basis(5, 1),
    lambda: B.derivative_basis_matrix(5, [0.5], 3, -1),
    lambda: B.evaluate(np.zeros(5), [0.5]),
    lambda: B.evaluate(np.zeros((3, 2)), [0.5]),
    lambda: B.evaluate(np.full((5, 2), np.inf), [0.5]),
    lambda: B.sample_uniform(np.zeros((5, 2)), 0),
    lambda: B.bezier_segments(np.zeros((2, 2)), 2),
])
def test_bad_input_raises_input_error(call):
    with pytest.raises(InputError):
        call()


def test_round_off_outside_the_domain_is_clipped():
    ctrl = np.random.default_rng(0).normal(size=(6, 2))
    np.testing.assert_allclose(B.evaluate(ctrl, [-1e-14, 1 + 1e-14]), ctrl[[0, -1]], rtol=0, atol=1e-12)
