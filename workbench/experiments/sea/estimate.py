"""What every sea estimator returns: plain arrays, no knowledge of Rerun."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.estimation.angles import wrap
from workbench.experiments.sea import geometry
from workbench.experiments.sea.scenario import SeaData


@dataclass
class Estimate:
    """Per-step estimates of one estimator on one run; NaN where it has none."""

    name: str
    position: np.ndarray                  # (T, 2)
    alpha: np.ndarray                     # (T,)
    beta: np.ndarray                      # (T,)
    range: np.ndarray                     # (T,)
    seconds: float = 0.0
    covariance: np.ndarray | None = None  # (T, 2, 2) position covariance
    state_cov: np.ndarray | None = None   # (T, 4, 4) for NEES, where the estimator has one
    velocity: np.ndarray | None = None    # (T, 2)
    forecast: np.ndarray | None = None    # (T, L, 2) positions 1..L steps ahead of each step
    forecast_angles: np.ndarray | None = None  # (T, L, 2) alpha, beta ahead (algorithms 2-3)


def from_positions(name: str, data: SeaData, position: np.ndarray, **kw) -> Estimate:
    """An estimate from target positions, with its camera-relative angles and range.

    The angles the camera sees are relative to the *true* camera position, which the
    estimator knows only to ``sigma_observer``. Seen from the measured position, 1 m of
    observer error is 17' of azimuth at 200 m, far more than the camera's 0.88'. So the
    angles are the linear MMSE estimate: the predicted angles ``h(x, o~)`` plus the part of
    the innovation ``nu = z - h(x, o~)`` that the observer's noise and the estimate's own
    uncertainty explain, ``C (C + R0)^-1 nu`` with ``C = J (P + sigma_o^2 I) J'`` and
    ``R0 = diag(sigma_alpha^2, sigma_beta^2)``. Where the object is unseen, ``h(x, o~)``.
    """
    alpha, beta = geometry.angles(position, data.observer_meas, data.course, data.height)
    cov = kw.get("covariance")
    J = geometry.angle_jacobian(position, data.observer_meas, data.height)
    Px = np.zeros(J.shape) if cov is None else np.nan_to_num(cov)
    C = J @ (Px + data.sigma_observer**2 * np.eye(2)) @ np.swapaxes(J, -1, -2)
    S = C + np.diag([data.sigma_alpha**2, data.sigma_beta**2])
    nu = np.stack([wrap(data.alpha_meas - alpha), data.beta_meas - beta], axis=-1)
    ok = np.all(np.isfinite(nu), axis=-1) & np.all(np.isfinite(S), axis=(-1, -2))
    corr = np.zeros_like(nu)
    corr[ok] = (C[ok] @ np.linalg.solve(S[ok], nu[ok][..., None]))[..., 0]
    rng = np.hypot(*(position - data.observer_meas).T)
    return Estimate(name=name, position=position, alpha=alpha + corr[:, 0],
                    beta=beta + corr[:, 1], range=rng, **kw)


def from_angles(name: str, data: SeaData, alpha: np.ndarray, beta: np.ndarray, **kw) -> Estimate:
    """An estimate from angles through the geometric inverse (3)-(5)."""
    xy, d = geometry.position(alpha, beta, data.observer_meas, data.course, data.height)
    return Estimate(name=name, position=xy, alpha=alpha, beta=beta, range=d, **kw)
