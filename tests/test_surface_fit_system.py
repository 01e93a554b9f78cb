"""The fits' least-squares system: its normal equations against the rows they stand for."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from gsr_cad.reconstruct.surface import CG_UNKNOWNS, POINT_WEIGHT, _cg_step, _normal_equations, _solve_spd


def _dense_normal_equations(A: np.ndarray, normals: np.ndarray, goal: np.ndarray, weight: np.ndarray):
    """``J^T W J`` and ``J^T W y`` from the rows themselves: a point-to-plane row and three point-to-point rows
    (``POINT_WEIGHT``) per point, in the unknowns ``V.ravel()``."""
    q, n = A.shape
    rows, rhs, w = [], [], []
    for j in range(q):
        plane = np.kron(A[j], normals[j])  # d/dV of n_j . (A_j V)
        rows.append(plane)
        rhs.append(normals[j] @ goal[j])
        w.append(weight[j])
        for c in range(3):
            e = np.zeros(3)
            e[c] = 1.0
            rows.append(np.kron(A[j], e))
            rhs.append(goal[j, c])
            w.append(weight[j] * POINT_WEIGHT)
    J, y, w = np.array(rows), np.array(rhs), np.array(w)
    return J.T @ (w[:, None] * J), J.T @ (w * y)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_the_normal_equations_match_the_rows_they_stand_for(seed, axis_aligned):
    """Random sparse rows and normals (block-sparse assembly), and normals along the axes, whose cross terms
    vanish and leave the six products with different patterns (assembled as coordinates)."""
    rng = np.random.default_rng(seed)
    q, n = 40, 9
    dense = rng.random((q, n)) * (rng.random((q, n)) < 0.3)
    dense[np.arange(q), rng.integers(0, n, q)] = 1.0
    if axis_aligned:
        normals = np.eye(3)[rng.integers(0, 3, q)] * rng.choice([-1.0, 1.0], (q, 1))
    else:
        normals = rng.normal(size=(q, 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    goal, weight = rng.normal(size=(q, 3)), rng.random(q)
    H, g = _normal_equations(sp.csr_matrix(dense), normals, goal, weight)
    H_ref, g_ref = _dense_normal_equations(dense, normals, goal, weight)
    np.testing.assert_allclose(H.toarray(), H_ref, atol=1e-12)
    np.testing.assert_allclose(g, g_ref, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_the_symmetric_solve_matches_a_dense_one(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 40))
    B = sp.random(n, n, density=0.2, random_state=rng) + sp.identity(n)
    A = (B.T @ B + 1e-3 * sp.identity(n)).tocsc()  # symmetric positive definite, as a fit round's system
    b = rng.normal(size=n)
    np.testing.assert_allclose(_solve_spd(A, b), np.linalg.solve(A.toarray(), b), rtol=1e-8, atol=1e-10)


def test_a_singular_system_gives_no_step():
    A = sp.csc_matrix(np.array([[1.0, 2.0], [2.0, 4.0]]))
    assert np.isnan(_solve_spd(A, np.array([1.0, 1.0]))).all()


def _split_cube_system(splits: int, damping: float):
    """A fit round's damped normal equations on a split cube's cage (valence-3 corners, refined locally), its
    target points the limit surface's samples moved off it."""
    from gsr_cad.geometry import subdivision
    from gsr_cad.geometry.limit_surface import LimitSurface, get_layout
    from gsr_cad.geometry.polymesh import unit_cube

    cube = unit_cube()
    mesh = subdivision.get_catmull_clark(cube, splits, "all").refine(cube.vertices)
    surface = LimitSurface(get_layout(mesh, "all", 5), mesh.vertices)
    rng = np.random.default_rng(splits)
    on = surface.samples()[0].point
    points = on[rng.integers(0, len(on), 6000)] + rng.normal(0.0, 0.02, (6000, 3))
    hits = surface.closest(points)
    H, g = _normal_equations(surface.rows(hits), hits.normal, points, np.full(6000, 1.0 / 6000))
    return (H + damping * float(H.diagonal().mean()) * sp.identity(H.shape[0], format="csc")).tocsc(), g


def test_conjugate_gradients_give_the_factored_step_on_a_large_cage():
    """The solve of cages of CG_UNKNOWNS and more: block-Jacobi conjugate gradients against SuperLU's factor."""
    A, g = _split_cube_system(4, 1e-3)
    assert A.shape[0] >= CG_UNKNOWNS
    exact = _solve_spd(A, g)
    step = _cg_step(A, g)
    assert step is not None
    assert np.abs(step - exact).max() <= 1e-4 * np.abs(exact).max()


def test_conjugate_gradients_that_do_not_converge_leave_the_solve_to_the_factor():
    rng = np.random.default_rng(0)
    n = 300
    Q = np.linalg.qr(rng.normal(size=(3 * n, 3 * n)))[0]
    # eigenvalues spread over twelve decades: more iterations than CG_ITERATIONS to a residual of 1e-8
    stiff = sp.csc_matrix(Q @ np.diag(np.logspace(-12, 0, 3 * n)) @ Q.T)
    assert _cg_step(stiff, rng.normal(size=3 * n)) is None
    singular = sp.csc_matrix((3 * n, 3 * n))
    assert _cg_step(singular, np.ones(3 * n)) is None
