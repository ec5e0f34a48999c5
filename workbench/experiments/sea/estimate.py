"""What every sea estimator returns: plain arrays, no knowledge of Rerun.

A researcher's estimator ``my_filter(data: SeaData, cfg: SeaConfig) -> Estimate`` needs to fill
``position`` only; the camera-relative angles and range are derived from it (by
:func:`from_positions`) where left out. The frame is the sea's: x east, y north, metres, the
camera at ``data.observer`` (true) / ``data.observer_meas`` (what an estimator knows), height
``data.height``; ``data.target`` is the truth (for evaluation; an estimator must not read it).
Rows are steps ``data.t``; a row of NaN is "no estimate at this step" (a partly-NaN row is an
error); covariances must be symmetric positive semi-definite where the position is finite.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.estimation.angles import wrap
from workbench.estimation.consistency import Innovations
from workbench.experiments.sea import geometry
from workbench.experiments.sea.scenario import SeaData


@dataclass
class Estimate:
    """Per-step estimates of one estimator on one run; NaN where it has none."""

    name: str = ""                        # set by the workbench from the estimator table
    position: np.ndarray | None = None    # (T, 2) x, y of the object, m (required)
    alpha: np.ndarray | None = None       # (T,) azimuth from the course, rad [derived from position]
    beta: np.ndarray | None = None        # (T,) elevation below the horizon, rad [derived]
    range: np.ndarray | None = None       # (T,) horizontal range from the measured camera, m [derived]
    seconds: float = 0.0                  # set by the workbench
    covariance: np.ndarray | None = None  # (T, 2, 2) position covariance, m^2
    state_cov: np.ndarray | None = None   # (T, 4, 4) of (x, y, vx, vy), for NEES (needs velocity)
    velocity: np.ndarray | None = None    # (T, 2) m/s
    forecast: np.ndarray | None = None    # (T, L, 2) positions 1..L steps ahead of each step
    forecast_angles: np.ndarray | None = None  # (T, L, 2) alpha, beta ahead (algorithms 2-3)
    innovations: Innovations | None = None     # a filter's innovations of (alpha, beta), for its truth-free checks


def from_positions(name: str, data: SeaData, position: np.ndarray, **kw) -> Estimate:
    """An estimate from target positions, with its camera-relative angles and range.

    The angles the camera sees are relative to the *true* camera position, which the
    estimator knows only to ``sigma_observer``. Seen from the measured position, 1 m of
    observer error is 17' of azimuth at 200 m, far more than the camera's 0.88'. So the
    angles are the linear MMSE estimate: the predicted angles ``h(x, o~)`` plus the part of
    the innovation ``nu = z - h(x, o~)`` that the observer's noise and the estimate's own
    uncertainty explain, ``C (C + R0)^-1 nu`` with ``C = J (P + sigma_o^2 I) J'`` and
    ``R0 = diag(sigma_alpha^2, sigma_beta^2)``. Where the object is unseen, ``h(x, o~)``.
    This is for an estimate that knows the camera by its fixes alone (algorithms 1-3, a
    researcher's); the model-based estimators hold the camera's offset and report the angles of
    their own relative estimate (:func:`.observer.relative`).
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


def check(est: Estimate, data: SeaData, cfg, estimator) -> Estimate:
    """An estimator's answer against this type's contract (shapes, whole-row NaNs, PSD
    covariances); the angles and range derived from the position where left out; the name set.
    Raises :class:`~workbench.core.estimator.EstimateError` naming what is wrong."""
    from workbench.core.estimator import EstimateError, as_array, psd, whole_rows

    if not isinstance(est, Estimate):
        raise EstimateError(f"returned {type(est).__name__}, not a sea Estimate")
    T = data.steps
    if est.position is None:
        raise EstimateError("the estimate has no position")
    pos = as_array(est.position, "position", (T, 2))
    ok = whole_rows(pos, "position", allow_empty=False)
    cov = None if est.covariance is None else as_array(est.covariance, "covariance", (T, 2, 2))
    if cov is not None:
        psd(cov, "covariance", ok, estimator)
    if est.state_cov is not None:
        sc = as_array(est.state_cov, "state_cov", (T, 4, 4))
        if est.velocity is None:
            raise EstimateError("state_cov needs velocity")
        psd(sc, "state_cov", None, estimator)
    if est.velocity is not None:
        whole_rows(as_array(est.velocity, "velocity", (T, 2)), "velocity")
    if est.forecast is not None:  # (a forecast may lack some horizons: an angle above the horizon)
        as_array(est.forecast, "forecast", (T, None, 2))
    if est.forecast_angles is not None:
        as_array(est.forecast_angles, "forecast_angles", (T, None, 2))
    est.name = estimator.name
    if est.alpha is None or est.beta is None or est.range is None:
        derived = from_positions(est.name, data, pos, covariance=cov)
        est.alpha = derived.alpha if est.alpha is None else est.alpha
        est.beta = derived.beta if est.beta is None else est.beta
        est.range = derived.range if est.range is None else est.range
    for what in ("alpha", "beta", "range"):
        setattr(est, what, as_array(getattr(est, what), what, (T,)))
    est.position = pos
    return est
