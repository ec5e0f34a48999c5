"""The sea paper's measurement model (1)-(2) and its geometric inverse (3)-(5)."""

from __future__ import annotations

import numpy as np


def angles(target_xy: np.ndarray, observer_xy: np.ndarray, course: np.ndarray | float,
           height: float) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and elevation (1)-(2) of a sea-level target from a camera at ``height``.

    ``e = target - observer``; ``p = -e_x sin psi + e_y cos psi``, ``r = e_x cos psi + e_y sin psi``,
    ``k = |e|``; ``alpha = atan2(p, r)`` (the paper writes atan(p/r); atan2 keeps the quadrant),
    ``beta = atan(h / k)``.
    """
    e = np.asarray(target_xy, float) - np.asarray(observer_xy, float)
    c, s = np.cos(course), np.sin(course)
    p = -e[..., 0] * s + e[..., 1] * c
    r = e[..., 0] * c + e[..., 1] * s
    k = np.hypot(e[..., 0], e[..., 1])
    return np.arctan2(p, r), np.arctan2(height, k)


def position(alpha: np.ndarray, beta: np.ndarray, observer_xy: np.ndarray,
             course: np.ndarray | float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Algorithm 1, the geometric estimate (3)-(5): ``(xy, d)`` from angles.

    ``d = h / tan(beta)``, ``x = x_o + d cos(alpha + psi)``, ``y = y_o + d sin(alpha + psi)``.
    An elevation at or above the horizon (``beta <= 0``) has no finite range: NaN.
    """
    beta = np.asarray(beta, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(beta > 0, height / np.tan(beta), np.nan)
    bearing = np.asarray(alpha) + course
    xy = np.asarray(observer_xy, float) + d[..., None] * np.stack(
        [np.cos(bearing), np.sin(bearing)], axis=-1)
    return xy, d


def angle_jacobian(target_xy: np.ndarray, observer_xy: np.ndarray, height: float) -> np.ndarray:
    """d(alpha, beta) / d(target x, y), shape ``(..., 2, 2)``; minus this is the observer's."""
    e = np.asarray(target_xy, float) - np.asarray(observer_xy, float)
    k2 = e[..., 0] ** 2 + e[..., 1] ** 2
    k = np.sqrt(k2)
    J = np.empty(e.shape[:-1] + (2, 2))
    J[..., 0, 0] = -e[..., 1] / k2
    J[..., 0, 1] = e[..., 0] / k2
    g = -height / ((k2 + height**2) * k)
    J[..., 1, 0] = g * e[..., 0]
    J[..., 1, 1] = g * e[..., 1]
    return J


def effective_noise(target_xy: np.ndarray, observer_xy: np.ndarray, height: float,
                    sigma_alpha: float, sigma_beta: float, sigma_observer: float,
                    jacobian: np.ndarray | None = None) -> np.ndarray:
    """Angle-noise covariance with the observer's position noise folded in, ``(..., 2, 2)``.

    One fix of the observer's position (1 m per axis in Table 1) taken on its own: linearising
    (1)-(2) in the observer position gives ``R = diag(sa^2, sb^2) + sigma_o^2 J J'``; at 700 m
    the observer's 1 m costs 4.9' of azimuth, more than the camera's 0.88'. The model-based
    estimators fold it in only where the platform's path is not known (:mod:`.observer`); the
    truth-free residual takes it for the fix each residual is seen from (:func:`.metrics.residual`).
    ``jacobian``, if given, is :func:`angle_jacobian` at these arguments (saves computing it twice).
    """
    J = angle_jacobian(target_xy, observer_xy, height) if jacobian is None else jacobian
    R = sigma_observer**2 * J @ np.swapaxes(J, -1, -2)
    R[..., 0, 0] += sigma_alpha**2
    R[..., 1, 1] += sigma_beta**2
    return R
