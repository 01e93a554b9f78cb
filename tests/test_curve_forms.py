"""Closed (periodic) and cornered curve forms against SciPy, their exact clamped form, and the two-sided distance."""

import numpy as np
import pytest
from scipy.interpolate import BSpline

from gsr_cad.errors import InputError
from gsr_cad.geometry import bspline
from gsr_cad.geometry.curveprep import corner_candidates, detect_closed, is_unordered, nearest_neighbour_order
from gsr_cad.geometry.distance import curve_to_points, data_model, point_to_polyline, two_sided

U = np.linspace(0.0, 1.0, 2001)


def ctrl(n, dim=2, seed=0):
    return np.random.default_rng(seed).normal(size=(n, dim))


@pytest.mark.parametrize("degree", [2, 3])
def test_periodic_form_is_scipy_periodic_bspline(degree):
    c = ctrl(9)
    spline = bspline.make_spline(c, degree, closed=True)
    # the textbook periodic uniform B-spline: wrapped coefficients on integer knots, domain [k, k + n]
    n, k = len(c), degree
    ref = BSpline(np.arange(n + 2 * k + 1, dtype=float), np.vstack([c, c[:k]]), k)
    np.testing.assert_allclose(spline(U), ref(k + n * U), atol=1e-13)
    for nu in range(degree):  # closes with C^(k-1) continuity
        np.testing.assert_allclose(spline(0.0, nu), spline(1.0 - 1e-12, nu), atol=1e-6 * max(1, 10 ** nu))
    np.testing.assert_allclose(bspline.form_design(n, U, degree, closed=True) @ c, spline(U), atol=1e-13)


@pytest.mark.parametrize("closed,corners", [(False, (3,)), (False, (3, 7)), (False, (4, 8)), (True, (0,)),
                                            (True, (2, 6)), (True, (11,))])
def test_corner_is_a_repeated_knot_through_its_control_point(closed, corners):
    c = ctrl(12, seed=len(corners))
    degree = 3
    t = bspline.form_knots(12, degree, closed, corners)
    spline = bspline.make_spline(c, degree, closed, corners)
    np.testing.assert_array_equal(spline.t, t)
    values, counts = np.unique(t, return_counts=True)
    assert np.count_nonzero(counts == degree) >= len(corners)
    for i in corners:  # the knot of multiplicity k at t[i+1..i+k] puts the curve on P_i, with a kink
        u = t[i + 1]
        assert t[i + 1] == t[i + degree]
        np.testing.assert_allclose(spline(u % 1.0), c[i], atol=1e-12)
        left, right = spline(u - 1e-7, 1), spline(u + 1e-7, 1)
        assert np.linalg.norm(left / np.linalg.norm(left) - right / np.linalg.norm(right)) > 1e-3
    np.testing.assert_allclose(bspline.form_design(12, U, degree, closed, corners) @ c, spline(U), atol=1e-12)


@pytest.mark.parametrize("closed,corners,degree,dim", [(False, (), 3, 2), (False, (3, 6), 3, 2), (True, (), 3, 2),
                                                       (True, (0, 5), 3, 3), (True, (4,), 3, 2), (True, (), 2, 2),
                                                       (True, (3,), 2, 3)])
def test_clamped_form_is_exact_and_end_interpolating(closed, corners, degree, dim):
    c = ctrl(10, dim, seed=3)
    knots, poles = bspline.clamped_form(c, degree, closed, corners)
    k = degree
    assert np.all(knots[:k + 1] == 0.0) and np.all(knots[-k - 1:] == 1.0) and np.all(np.diff(knots) >= 0)
    assert len(poles) == len(knots) - k - 1
    spline = bspline.make_spline(c, degree, closed, corners)
    np.testing.assert_allclose(BSpline(knots, poles, k)(U), spline(U), atol=1e-12)
    np.testing.assert_allclose(poles[0], spline(0.0), atol=1e-12)
    np.testing.assert_allclose(poles[-1], spline(0.0 if closed else 1.0), atol=1e-12)
    interior, mult = np.unique(knots[k + 1:-k - 1], return_counts=True)
    assert np.count_nonzero(mult == k) >= len(corners) - (1 if closed and 0 in corners else 0)


@pytest.mark.parametrize("n,closed,corners", [(6, False, (2,)), (6, False, (3, 4)), (8, True, (0, 2)), (3, True, ())])
def test_bad_corners_are_input_errors(n, closed, corners):
    with pytest.raises(InputError):
        bspline.form_knots(n, 3, closed, corners)


def brute_two_sided(spline, points, model):
    dense = spline(np.linspace(0.0, 1.0, 200_001))
    there = np.array([np.linalg.norm(dense - p, axis=1).min() for p in points])
    return there, point_to_polyline(dense[::50], model)


@pytest.mark.parametrize("closed,corners", [(False, ()), (True, ()), (True, (0, 4))])
def test_two_sided_distance_matches_brute_force(closed, corners):
    rng = np.random.default_rng(7)
    c = ctrl(9, seed=5)
    spline = bspline.make_spline(c, 3, closed, corners)
    points = spline(rng.uniform(0, 1, 60)) + rng.normal(0, 0.02, (60, 2))
    points = points[np.argsort(np.arctan2(points[:, 1], points[:, 0]))]
    there, back = two_sided(spline, points, closed, per_span=64)
    model = data_model(points, closed)
    ref_there, ref_back = brute_two_sided(spline, points, model)
    np.testing.assert_allclose(there, ref_there, atol=1e-6)
    assert abs(back.max() - ref_back.max()) < 2e-3 * np.ptp(points)  # both sample the curve, at different places


def test_curve_to_points_sees_an_excursion_the_data_to_curve_side_misses():
    t = np.linspace(0, 1, 41)
    data = np.column_stack([t, np.zeros_like(t)])
    loop = np.array([[0, 0], [0.45, 0], [0.5, 0.8], [0.55, 0], [1, 0]], float)  # a spike between two samples
    spline = bspline.make_spline(np.vstack([loop[:1], loop[:2], loop[1:4], loop[3:], loop[-1:]]), 3)
    back = curve_to_points(spline, data, per_span=32)
    assert back.max() > 0.2


def test_data_model_passes_through_the_data_and_follows_a_circle():
    th = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    p = np.column_stack([np.cos(th), np.sin(th)])
    model = data_model(p, closed=True, per_segment=8)
    np.testing.assert_allclose(model[::8][:40], p, atol=1e-15)
    assert np.abs(np.linalg.norm(model, axis=1) - 1.0).max() < 1e-4 < 1 - np.cos(np.pi / 40)
    sq = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2]], float)
    np.testing.assert_allclose(point_to_polyline(data_model(sq, False, corners=[2]), sq), 0.0, atol=1e-15)


def test_closed_detection_relative_to_spacing():
    th = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    ring = np.column_stack([np.cos(th), np.sin(th)])
    assert detect_closed(ring) and detect_closed(np.vstack([ring, ring[:1]]))
    assert not detect_closed(ring[:90])  # a 36-degree gap is ten spacings wide
    arc = np.column_stack([np.linspace(0, 1, 50), np.zeros(50)])
    assert not detect_closed(arc)


def test_ordering_detection_and_nearest_neighbour_order():
    t = np.linspace(0, 1, 400)
    curve = np.column_stack([t, 0.3 * np.sin(6 * t)])
    assert not is_unordered(curve)
    sparse = curve[np.sort(np.random.default_rng(1).choice(400, 100, replace=False))]
    assert not is_unordered(sparse)
    shuffled = curve[np.random.default_rng(2).permutation(400)]
    assert is_unordered(shuffled)
    ordered = shuffled[nearest_neighbour_order(shuffled)]
    steps = np.linalg.norm(np.diff(ordered, axis=0), axis=1)
    assert steps.max() < 5 * np.median(np.linalg.norm(np.diff(curve, axis=0), axis=1))
    cloud = np.random.default_rng(3).uniform(size=(300, 2))  # no curve at all
    with pytest.raises(InputError):
        nearest_neighbour_order(cloud)


def test_corner_candidates_find_polygon_corners_not_smooth_bends():
    sq = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    pts = np.vstack([a + np.linspace(0, 1, 100, endpoint=False)[:, None] * (b - a)
                     for a, b in zip(sq, np.roll(sq, -1, axis=0))])
    np.testing.assert_array_equal(corner_candidates(pts, closed=True), [0, 100, 200, 300])
    th = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    ellipse = np.column_stack([3 * np.cos(th), 0.5 * np.sin(th)])
    assert corner_candidates(ellipse, closed=True).size == 0


def test_closed_chaikin_converges_to_the_periodic_quadratic_bspline():
    from gsr_cad.geometry.chaikin import refine_closed
    from gsr_cad.geometry.distance import point_to_spline

    c = ctrl(7, seed=9)
    fine = refine_closed(c, 7)
    assert len(fine) == 7 * 2 ** 7
    spline = bspline.make_spline(c, 2, closed=True)
    assert point_to_spline(spline, fine, periodic=True).max() < 1e-4 * np.ptp(c)
    np.testing.assert_allclose(refine_closed(c, 1)[:2], [0.75 * c[0] + 0.25 * c[1], 0.25 * c[0] + 0.75 * c[1]])


@pytest.mark.parametrize("closed,corners", [(False, ()), (True, ()), (True, (0, 4)), (False, (3, 6))])
def test_bezier_pieces_of_any_clamped_form_are_exact(closed, corners):
    c = ctrl(10, seed=11)
    knots, poles = bspline.clamped_form(c, 3, closed, corners)
    pieces, brk, spline = bspline.bezier_pieces(knots, poles, 3), np.unique(knots), BSpline(knots, poles, 3)
    assert len(pieces) == len(brk) - 1
    u = np.linspace(0, 1, 11)
    basis = np.stack([(1 - u) ** 3, 3 * u * (1 - u) ** 2, 3 * u ** 2 * (1 - u), u ** 3], axis=1)
    for j, piece in enumerate(pieces):
        np.testing.assert_allclose(basis @ piece, spline(brk[j] + u * (brk[j + 1] - brk[j])), atol=1e-12)
