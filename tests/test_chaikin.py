"""Chaikin refinement: midpoint knot insertion (FITPACK's insert as oracle), converging to the quadratic B-spline."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline, insert

from gsr_cad.errors import InputError
from gsr_cad.geometry import bspline as B
from gsr_cad.geometry import chaikin as C


def inserted_midpoints(points):
    """Control polygon after inserting every span midpoint into the clamped quadratic B-spline (FITPACK)."""
    n = len(points)
    t = B.clamped_uniform_knots(n, 2)
    cols = []
    for dim in range(points.shape[1]):
        tck = (t, points[:, dim], 2)
        for u in (np.arange(n - 2) + 0.5) / (n - 2):
            tck = insert(u, tck)
        cols.append(np.asarray(tck[1])[: 2 * n - 2])
    return np.stack(cols, axis=1)


def test_limit_degree_is_quadratic():
    assert C.limit_degree == 2


def test_one_step_follows_the_stated_rule():
    p = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 8.0], [0.0, 8.0], [-4.0, 4.0]])
    expected = [p[0], (p[0] + p[1]) / 2,
                0.75 * p[1] + 0.25 * p[2], 0.25 * p[1] + 0.75 * p[2],
                0.75 * p[2] + 0.25 * p[3], 0.25 * p[2] + 0.75 * p[3],
                (p[3] + p[4]) / 2, p[4]]
    np.testing.assert_array_equal(C.refine(p), np.array(expected))


@pytest.mark.parametrize("n", range(3, 16))
def test_refine_equals_midpoint_knot_insertion(n):
    p = np.random.default_rng(n).normal(size=(n, 2)) * 3
    np.testing.assert_allclose(C.refine(p), inserted_midpoints(p), rtol=0, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(3, 12), levels=st.integers(0, 4), dim=st.integers(1, 3), seed=st.integers(0, 2**32 - 1))
def test_refined_polygon_describes_the_same_quadratic_curve(n, levels, dim, seed):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, dim))
    q = C.refine(p, levels)
    assert q.shape == (2**levels * (n - 2) + 2, dim)
    np.testing.assert_array_equal(q[[0, -1]], p[[0, -1]])
    x = np.concatenate([[0.0, 1.0], rng.random(40)])
    t_p, t_q = B.clamped_uniform_knots(n, 2), B.clamped_uniform_knots(len(q), 2)
    np.testing.assert_allclose(BSpline(t_q, q, 2)(x), BSpline(t_p, p, 2)(x), rtol=0, atol=1e-12)


def test_refinement_matrix_is_cached_read_only_and_composes():
    m = C.refinement_matrix(6, 3)
    assert isinstance(m, sp.csr_matrix)
    assert m is C.refinement_matrix(6, 3)
    assert m.shape == (8 * 4 + 2, 6)
    assert not m.data.flags.writeable
    np.testing.assert_allclose(np.asarray(m.sum(axis=1)).ravel(), 1.0, rtol=0, atol=1e-15)
    steps = C.refinement_matrix(6, 1)
    steps = C.refinement_matrix(10, 1) @ steps
    steps = C.refinement_matrix(18, 1) @ steps
    np.testing.assert_allclose(m.toarray(), steps.toarray(), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(C.refinement_matrix(6, 0).toarray(), np.eye(6))


def test_repeated_refinement_converges_to_the_quadratic_bspline_at_rate_four():
    p = np.random.default_rng(3).normal(size=(7, 2))
    errors = []
    for levels in range(1, 8):
        q = C.refine(p, levels)
        t = B.clamped_uniform_knots(len(q), 2)
        greville = (t[1:len(q) + 1] + t[2:len(q) + 2]) / 2
        errors.append(np.abs(q - BSpline(B.clamped_uniform_knots(7, 2), p, 2)(greville)).max())
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.02)


@pytest.mark.parametrize("call", [
    lambda: C.refine(np.zeros((2, 2))),
    lambda: C.refine(np.zeros(5)),
    lambda: C.refine(np.full((4, 2), np.nan)),
    lambda: C.refine(np.zeros((4, 2)), -1),
    lambda: C.refinement_matrix(5, 1.5),
])
def test_bad_input_raises_input_error(call):
    with pytest.raises(InputError):
        call()
