"""Least-squares placement: exact on exact data, independent of sample spacing in geometric mode."""

import numpy as np
from scipy.interpolate import BSpline

from gsr_cad.geometry.bspline import clamped_uniform_knots
from gsr_cad.geometry.curvefit import fit_curve, solve_interior


def truth_curve(n=7, seed=3):
    rng = np.random.default_rng(seed)
    ctrl = np.column_stack([np.linspace(0, 10, n), rng.uniform(-3, 3, n)])
    return ctrl, BSpline(clamped_uniform_knots(n, 3), ctrl, 3)


def test_index_fit_recovers_control_points_exactly():
    ctrl, spline = truth_curve()
    pts = spline(np.linspace(0, 1, 200))
    fit = fit_curve(pts, len(ctrl), 3, parametrization="index")
    np.testing.assert_allclose(fit.ctrl, ctrl, atol=1e-9)
    assert fit.distances.max() < 1e-9


def test_geometric_fit_handles_uneven_sampling():
    ctrl, spline = truth_curve()
    t = np.sort(np.random.default_rng(5).uniform(0, 1, 60))
    t[0], t[-1] = 0.0, 1.0
    pts = spline(t)
    index_fit = fit_curve(pts, len(ctrl), 3, parametrization="index")
    geo_fit = fit_curve(pts, len(ctrl), 3, parametrization="geometric", iterations=200)
    diag = np.linalg.norm(np.ptp(pts, axis=0))
    assert geo_fit.rms < 0.2 * index_fit.rms
    assert geo_fit.rms / diag < 5e-4


def test_bounded_solve_stays_in_box():
    ctrl, spline = truth_curve()
    pts = spline(np.linspace(0, 1, 100))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    free = solve_interior(pts, 7, np.linspace(0, 1, 100), 3)
    assert np.any(free < lo - 1e-9) or np.any(free > hi + 1e-9)  # so the bounded solve is what keeps it inside
    sol = solve_interior(pts, 7, np.linspace(0, 1, 100), 3, lo, hi)
    assert np.all(sol >= lo - 1e-12) and np.all(sol <= hi + 1e-12)
    np.testing.assert_array_equal(sol[0], pts[0])
    np.testing.assert_array_equal(sol[-1], pts[-1])


def _brute_force(pts, n, params, closed, weights=None):
    """Least squares through a dense basis and numpy's lstsq (the reference for the row-wise solver)."""
    from gsr_cad.geometry.bspline import form_design

    basis = form_design(n, params, 3, closed=closed).toarray()
    rhs = pts.copy()
    if not closed:
        rhs = rhs - basis[:, [0]] * pts[0] - basis[:, [-1]] * pts[-1]
        basis = basis[:, 1:-1]
    root = np.sqrt(weights if weights is not None else np.ones(len(pts)))[:, None]
    sol = np.linalg.lstsq(basis * root, rhs * root, rcond=None)[0]
    return sol if closed else np.vstack([pts[:1], sol, pts[-1:]])


def test_row_wise_solver_matches_a_dense_least_squares_solve():
    rng = np.random.default_rng(11)
    for closed in (False, True):
        for n, m in ((6, 40), (40, 300), (150, 900)):  # dense Cholesky, and the banded / cyclic paths
            u = np.sort(rng.uniform(0, 1, m))
            if not closed:
                u[0], u[-1] = 0.0, 1.0
            pts = np.column_stack([np.cos(7 * u), np.sin(5 * u), u ** 2]) + rng.normal(0, 0.01, (m, 3))
            w = rng.uniform(0.5, 2.0, m)
            for weights in (None, w):
                got = solve_interior(pts, n, u, 3, weights=weights, closed=closed)
                want = _brute_force(pts, n, u, closed, weights)
                np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max())


def test_joint_step_converges_where_alternating_correction_creeps():
    from gsr_cad.geometry.curvefit import joint_refine

    ctrl, spline = truth_curve(n=9, seed=4)
    rng = np.random.default_rng(2)
    t = np.concatenate([[0.0], np.sort(rng.choice(np.linspace(0, 1, 200)[1:-1], 48, replace=False)), [1.0]])
    pts = spline(t)
    diag = np.linalg.norm(np.ptp(pts, axis=0))
    alternating = fit_curve(pts, 9, 3, iterations=100)
    joint = joint_refine(pts, alternating, 3)
    assert joint.rms <= alternating.rms
    assert joint.rms / diag < 1e-10 < alternating.rms / diag
    assert fit_curve(pts, 9, 3, iterations=100, joint=True).rms / diag < 1e-10


def test_sparse_fit_restarts_from_finer_fits_out_of_a_parametrisation_minimum():
    from gsr_cad.geometry.curvefit import CurveFit, _project, joint_refine
    from gsr_cad.reconstruct.samples import get_sample

    base = get_sample("bspline_12")  # a 12-point pigtail with a loop, 75 % of its samples removed at random
    dense = np.asarray(base.points)
    rng = np.random.default_rng([0, sum(map(ord, base.name)), 6])
    inner = np.sort(rng.choice(np.arange(1, len(dense) - 1), size=48, replace=False))
    pts = dense[np.concatenate([[0], inner, [len(dense) - 1]])]
    diag = np.linalg.norm(np.ptp(pts, axis=0))
    uniform = np.linspace(0.0, 1.0, len(pts))
    ctrl = solve_interior(pts, 12, uniform, 3)
    cold = joint_refine(pts, CurveFit(ctrl, *_project(ctrl, pts, uniform, 3, False)), 3)
    assert cold.rms / diag > 1e-6  # the joint step alone ends in a local minimum of the parametrisation
    fit = fit_curve(pts, 12, 3, iterations=100, joint=True)
    assert fit.rms / diag < 1e-12
    np.testing.assert_allclose(fit.ctrl, base.truth_ctrl, atol=1e-9)
    assert fit_curve(pts, 11, 3, iterations=100, joint=True).rms / diag > 1e-6  # one point fewer is not exact


def test_tangent_refine_reaches_the_joint_optimum_of_noisy_data():
    from gsr_cad.geometry.curvefit import joint_refine, tangent_refine

    ctrl, spline = truth_curve(n=7, seed=5)
    pts = spline(np.linspace(0, 1, 120))
    diag = np.linalg.norm(np.ptp(pts, axis=0))
    pts = pts + np.random.default_rng(1).normal(0.0, 0.007 * diag, pts.shape)
    for closed in (False, True):
        alternating = fit_curve(pts, 7, 3, iterations=25, closed=closed)
        refined = tangent_refine(pts, alternating, 3)
        reference = joint_refine(pts, alternating, 3, max_evaluations=400)  # dense Levenberg-Marquardt
        assert refined.rms < alternating.rms * (1 - 1e-3)
        assert refined.rms <= reference.rms * (1 + 1e-4)
        assert refined.closed == closed
