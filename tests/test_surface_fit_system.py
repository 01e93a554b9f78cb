"""The fits' least-squares system: its normal equations against the rows they stand for."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from gsr_cad.reconstruct.surface import POINT_WEIGHT, _normal_equations, _solve_spd


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
