"""Kalman-filter building blocks (filterpy-style names: x, P, F, Q, H, R, K, S).

Covariances are kept symmetric positive definite: the update uses the Joseph form.
"""

from __future__ import annotations

import numpy as np


def cv_transition(dt: float, axes: int = 2) -> np.ndarray:
    """Constant-velocity transition for the state ``[pos (axes), vel (axes)]``."""
    eye = np.eye(axes)
    return np.block([[eye, dt * eye], [np.zeros((axes, axes)), eye]])


def cv_noise_discrete(dt: float, sigma_acc: float, axes: int = 2) -> np.ndarray:
    """Discrete white-noise-acceleration Q (Bar-Shalom et al. 2001, 6.3.3).

    ``x+ = x + dt v + dt^2/2 w``, ``v+ = v + dt w``, w ~ N(0, sigma_acc^2) per axis: exactly
    the sea paper's target model. It is singular (one noise per axis drives two states).
    """
    g = np.array([[dt**2 / 2.0], [dt]])
    block = sigma_acc**2 * (g @ g.T)
    return _per_axis(block, axes)


def cv_noise_continuous(dt: float, q: float, axes: int = 2) -> np.ndarray:
    """Continuous white-noise-acceleration Q with spectral density ``q`` (full rank)."""
    block = q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    return _per_axis(block, axes)


def _per_axis(block: np.ndarray, axes: int) -> np.ndarray:
    """Lay a 2x2 (pos, vel) block out over the ``[pos..., vel...]`` ordering."""
    q = np.zeros((2 * axes, 2 * axes))
    for a in range(axes):
        idx = [a, axes + a]
        q[np.ix_(idx, idx)] = block
    return q


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray):
    """Linear prediction ``x = F x``, ``P = F P F' + Q``."""
    x = F @ x
    P = F @ P @ F.T + Q
    return x, 0.5 * (P + P.T)


def update(x: np.ndarray, P: np.ndarray, residual: np.ndarray, H: np.ndarray, R: np.ndarray):
    """Kalman update with a given innovation; Joseph form keeps P symmetric PD.

    Returns ``(x, P, S)`` with S the innovation covariance.
    """
    S = H @ P @ H.T + R
    K = np.linalg.solve(S.T, (P @ H.T).T).T
    x = x + K @ residual
    ikh = np.eye(len(x)) - K @ H
    P = ikh @ P @ ikh.T + K @ R @ K.T
    return x, 0.5 * (P + P.T), S
