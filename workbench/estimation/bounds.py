"""Cramér-Rao bounds for estimators of a state that evolves and is measured with additive
Gaussian noise: the posterior (Bayesian) bound of Tichavský, Muravchik and Nehorai, "Posterior
Cramér-Rao bounds for discrete-time nonlinear filtering", IEEE Trans. Signal Processing 46(5),
1998.

Model: ``x_{k+1} = f(x_k) + w_k``, ``w_k ~ N(0, Q)``; ``z_k = h_k(x_k) + v_k``, ``v_k ~ N(0, R_k)``;
``x_0 ~ N(m_0, P_0)``. With ``F_k`` the Jacobian of f and ``H_k`` that of h at the true state,
the information of x_k from z_0..z_k obeys (their eq. (21) with (34)-(36), in the covariance form
that also takes a singular Q):

    J_0 = P_0^{-1} + E[H_0' R_0^{-1} H_0],
    J_{k+1} = (Q + F_k J_k^{-1} F_k')^{-1} + E[H_{k+1}' R_{k+1}^{-1} H_{k+1}],

and any estimator's error covariance from the same data is at least ``J_k^{-1}`` (the filtering
bound). An estimator of x_k from the whole run z_0..z_N is bounded by the diagonal block of
the inverse of the whole trajectory's information, which is block tridiagonal; its diagonal
blocks come from the filtering bound by the Rauch-Tung-Striebel recursion (the smoothing bound).
The expectations are over the true trajectories: Monte Carlo runs give them as averages of the
per-run information terms (:func:`measurement_information`).
"""

from __future__ import annotations

import numpy as np


def measurement_information(H: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``H' R^{-1} H`` per step, ``H (T, m, n)``, ``R (T, m, m)`` (or one for all); rows of H
    that are NaN (no measurement at that step) give zero information."""
    H = np.asarray(H, float)
    R = np.broadcast_to(np.asarray(R, float), H.shape[:-2] + (H.shape[-2], H.shape[-2]))
    ok = np.isfinite(H).all(axis=(-1, -2)) & np.isfinite(R).all(axis=(-1, -2))
    out = np.zeros(H.shape[:-2] + (H.shape[-1], H.shape[-1]))
    if ok.any():
        h, r = H[ok], R[ok]
        out[ok] = np.swapaxes(h, -1, -2) @ np.linalg.solve(r, h)
    return out


def filtering(P0: np.ndarray, F: np.ndarray, Q: np.ndarray, info: np.ndarray) -> np.ndarray:
    """The filtering bound ``J_k^{-1}`` for every step, ``(T, n, n)``: the recursion above from
    the prior covariance ``P0``, the transition ``F`` and process noise ``Q`` (one for all steps
    or one per step ``(T, n, n)``, the step k -> k+1 at index k) and the measurement information
    ``info (T, n, n)`` (:func:`measurement_information`, averaged over runs)."""
    return filtering_and_prediction(P0, F, Q, info)[0]


def filtering_and_prediction(P0: np.ndarray, F: np.ndarray, Q: np.ndarray, info: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`filtering`, and the information of each step's prediction ``(F P_{k-1} F' + Q)^{-1}``
    (index k; the prior's at 0), which :func:`smoothing` inverts again if not given it."""
    info = np.asarray(info, float)
    T, n = info.shape[0], info.shape[-1]
    F = np.broadcast_to(np.asarray(F, float), (T, n, n))
    Q = np.broadcast_to(np.asarray(Q, float), (T, n, n))
    out = np.empty((T, n, n))
    predicted = np.empty((T, n, n))
    P = np.asarray(P0, float)
    for k in range(T):
        if k > 0:
            P = F[k - 1] @ P @ F[k - 1].T + Q[k - 1]
        predicted[k] = _inverse(P)
        P = _inverse(predicted[k] + info[k])
        out[k] = P
    return out, predicted


def smoothing(filtered: np.ndarray, F: np.ndarray, Q: np.ndarray,
              predicted_information: np.ndarray | None = None) -> np.ndarray:
    """The smoothing bound from the filtering bound (:func:`filtering`), ``(T, n, n)``: the
    diagonal blocks of the inverse of the whole trajectory's information, by the RTS recursion
    ``C_k = P_k F' (F P_k F' + Q)^{-1}``, ``S_k = P_k + C_k (S_{k+1} - F P_k F' - Q) C_k'``.
    ``predicted_information``: :func:`filtering_and_prediction`'s, for the same ``F`` and ``Q``
    (the inverse of ``F P_k F' + Q`` is its entry k + 1: the same product of the same operands,
    so the same bits; a third of the bounds' inverses saved)."""
    P = np.asarray(filtered, float)
    T, n = P.shape[0], P.shape[-1]
    F = np.broadcast_to(np.asarray(F, float), (T, n, n))
    Q = np.broadcast_to(np.asarray(Q, float), (T, n, n))
    out = np.empty_like(P)
    out[-1] = P[-1]
    for k in range(T - 2, -1, -1):
        pred = F[k] @ P[k] @ F[k].T + Q[k]
        inv = _inverse(pred) if predicted_information is None else predicted_information[k + 1]
        C = P[k] @ F[k].T @ inv
        S = P[k] + C @ (out[k + 1] - pred) @ C.T
        out[k] = 0.5 * (S + S.T)
    return out


def _inverse(A: np.ndarray) -> np.ndarray:
    """The inverse of a symmetric positive (semi-)definite matrix, symmetrised."""
    try:
        inv = np.linalg.inv(A)
    except np.linalg.LinAlgError:  # singular: the information of a direction nothing has observed
        inv = np.linalg.pinv(A, hermitian=True)
    return 0.5 * (inv + inv.T)


def efficiency(rmse: float, bound_variance: float) -> float:
    """``RMSE / sqrt(bound)``: 1 is as good as any estimator can be; under 1 by more than the
    Monte Carlo error means the estimator (or the bound) is wrong."""
    if not (np.isfinite(rmse) and np.isfinite(bound_variance)) or bound_variance <= 0:
        return float("nan")
    return float(rmse / np.sqrt(bound_variance))
