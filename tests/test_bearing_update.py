"""The EKF's compiled bearing update (``omni/algorithms/bearing_update.py``) against the update
written as matrix products: ``H`` of (9) built whole, ``S = H P H' + R``, ``K = P H' S^-1``,
``x + K nu``, ``P - K S K'``, and the second-order terms from their traces."""

from __future__ import annotations

import numpy as np

from workbench.estimation.angles import wrap
from workbench.experiments.omni.algorithms import bearing_update


def _dense(x: np.ndarray, P: np.ndarray, off: np.ndarray, bearings: np.ndarray, r: np.ndarray, second: bool):
    m, n = len(off), len(x)
    dx, dy = x[off] - x[0], x[off + 1] - x[1]
    q = dx * dx + dy * dy
    H = np.zeros((m, n))
    H[np.arange(m), 0], H[np.arange(m), 1], H[np.arange(m), 2] = dy / q, -dx / q, -1.0
    H[np.arange(m), off], H[np.arange(m), off + 1] = -dy / q, dx / q
    nu = wrap(bearings - (np.arctan2(dy, dx) - x[2]))
    S = H @ P @ H.T + np.diag(r)
    if second:
        for i, o in enumerate(off):
            a, b = dx[i], dy[i]
            B = np.array([[2 * a * b, b * b - a * a], [b * b - a * a, -2 * a * b]]) / q[i] ** 2
            C = P[o:o + 2, o:o + 2] + P[:2, :2] - P[o:o + 2, :2] - P[:2, o:o + 2]
            nu[i] = wrap(nu[i] - 0.5 * np.trace(B @ C))
            S[i, i] += 0.5 * np.trace(B @ C @ B @ C)
    return nu, S, P @ H.T


def _state(rng: np.random.Generator, n_lm: int = 5):
    n = 3 + 2 * n_lm
    x = rng.normal(size=n) * 3.0
    x[2] = 3.1   # a heading near pi, so the innovations wrap
    A = rng.normal(size=(n, n))
    return x, A @ A.T * 0.05 + np.eye(n) * 0.01


def test_a_hand_case():
    """A landmark 1 m ahead of a vehicle at the origin heading 0, ``P = I``: ``H = (0, -1, -1, 0, 1)``,
    so ``S = 3 + r``, ``nu`` the bearing itself, and the update's gain ``P H' / S``."""
    x = np.array([0.0, 0.0, 0.0, 1.0, 0.0])
    P = np.eye(5)
    nu, S, PH = bearing_update.innovations(x, P, np.array([3]), np.array([0.1]), np.array([0.5]), False)
    assert np.isclose(nu[0], 0.1, rtol=1e-14) and S[0, 0] == 3.5
    np.testing.assert_array_equal(PH[:, 0], [0.0, -1.0, -1.0, 0.0, 1.0])
    ok, xn, Pn, seq, w = bearing_update.corrected(x, P, nu, S, PH)
    assert ok and seq[0] == np.sqrt(3.5) and np.isclose(seq[0] * w[0], 0.1)
    np.testing.assert_allclose(xn, x + PH[:, 0] * 0.1 / 3.5, rtol=1e-15)
    np.testing.assert_allclose(Pn, P - np.outer(PH[:, 0], PH[:, 0]) / 3.5, rtol=1e-15, atol=1e-16)


def test_the_kernels_are_the_update_as_matrix_products():
    """Random states, three bearings at once, first and second order: ``nu``, ``S``, ``P H'``, the
    updated state and covariance, and the innovations one bearing at a time (``S``'s Cholesky
    factor's diagonal times ``L^-1 nu``) equal the dense products to round-off."""
    rng = np.random.default_rng(3)
    for trial in range(20):
        x, P = _state(rng)
        off = np.array([3, 7, 11])
        bearings = wrap(rng.uniform(-np.pi, np.pi, 3))
        r = rng.uniform(1e-4, 1e-2, 3)
        second = bool(trial % 2)
        nu, S, PH = bearing_update.innovations(x, P, off, bearings, r, second)
        want_nu, want_S, want_PH = _dense(x, P, off, bearings, r, second)
        np.testing.assert_allclose(nu, want_nu, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(S, want_S, rtol=1e-12)
        np.testing.assert_allclose(PH, want_PH, rtol=1e-12, atol=1e-14)
        ok, xn, Pn, seq, w = bearing_update.corrected(x, P, nu, S, PH)
        K = np.linalg.solve(S, PH.T).T
        L = np.linalg.cholesky(S)
        assert ok
        np.testing.assert_allclose(xn, x + K @ nu, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(Pn, P - K @ S @ K.T, rtol=1e-10, atol=1e-12)
        assert np.array_equal(Pn, Pn.T)
        np.testing.assert_allclose(seq * w, np.diag(L) * np.linalg.solve(L, nu), rtol=1e-12)


def test_an_indefinite_S_is_said_so():
    """``S`` not positive definite (the paper's augmentation can make it so): ``ok`` False and the
    state handed back unchanged, for the caller to solve by LU."""
    x, P = _state(np.random.default_rng(5), 2)
    S = np.array([[1.0, 2.0], [2.0, 1.0]])
    ok, xn, Pn, _, _ = bearing_update.corrected(x, P, np.array([0.1, 0.2]), S, np.ones((len(x), 2)))
    assert not ok and xn is x and Pn is P
