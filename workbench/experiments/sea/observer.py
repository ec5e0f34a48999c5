"""The camera's position as the model-based estimators know it: one unknown offset, learnt from
every fix (issue 27, item 5).

**The data.** The platform moves by its known velocity (``data.observer_velocity``: the paper's
observer flies a straight line at (2.55, 4.33) m/s, the AIS mast stands still, the UAV flies its
log) and its position is measured at every step with ``sigma_observer`` of white noise per axis
(:func:`.scenario.simulate`). So the true camera is ``o_k = c + d_k``, where ``d_k`` is the path
the known velocity gives from the start (dead reckoning, ``d_0 = 0``) and ``c`` is where the
platform started, unknown; each fix measures ``c``: ``m_k - d_k = c + n_k``. That is the
Cramér-Rao bound's model (:mod:`.bounds`: the camera in the state, moving by the known velocity,
measured every step).

**Before** this module the EKF, the smoothers and iSAM2 took each fix on its own and folded its
noise into that step's angle noise, ``R = diag(sa^2, sb^2) + sigma_o^2 J J'``
(:func:`.geometry.effective_noise`), as if the camera's error were new at every step. It is
not: it is the one offset, known after T fixes to ``sigma_o / sqrt(T)`` (3.7 cm on the paper's
721 steps). The folded model threw that away (at 700 m the 1 m fix costs 4.9' of azimuth against
the camera's 0.88'): on 100 paper runs the smoother's position efficiency was 1.70 +- 0.09, its
mean error 1.9 m along the line of sight, outwards (the same with the folded noise weighted at
the true position instead of the geometric guess), and every model-based estimator's azimuth
2.5-4.9 times its bound. Holding the offset: 0.95 +- 0.05, 0.04 m, 1.00 (:mod:`.bounds`).

**Reading taken, and why it is exact.** The angles (1)-(2) see the object only relative to the
camera, ``e_k = x_k - o_k = (x_k - d_k) - c``. Moving ``c`` and the whole object track by the same
vector changes no angle, no motion factor (the velocities do not move) and no prior that holds
information (the object's start is diffuse; its velocity prior is a velocity). So the angles
inform the relative track alone and the fixes the offset alone: the posterior of (relative
track, offset) is the product of the two, exactly for the linear fixes and to each estimator's
own linearisation for the angles. An estimator with the offset as a variable (a 6-state EKF, a
graph with an offset shared by every bearing factor) therefore gives the same estimate as one that

1. runs in the platform's own frame, the camera on its dead-reckoned path ``d_k`` and known
   exactly there (the exact model ``--sigma-observer 0`` runs), and
2. adds the offset's estimate from the fixes it has seen, ``x = e + c^`` with covariance
   ``P_e + var(c^) I`` on the position (the velocity untouched), ``c^`` the mean of
   ``m_j - d_j`` over those fixes and ``var(c^) = sigma_o^2 / n`` (the diffuse prior, 1e4 m in
   the bound, moves it by ``(sigma_o / 1e4)^2`` of itself: left out).

A causal estimator has the fixes up to step k (``n = k + 1``; the camera is fixed at every
step, seen or not), a smoother of the whole run all of them, a fixed-lag smoother those up to
its lag. ``tests/test_sea_observer.py`` checks the equivalence against an EKF with the offset in
its state. The angles and range an estimator reports are those of its relative estimate,
``e_k`` seen from ``d_k``: the object from the camera as the estimator holds both, known to the
estimate's own uncertainty (no correction from the innovation: the estimate already holds the
step's measurement, :func:`relative`).

The dead-reckoned path is the trapezoidal integral of the known velocity: exact for the paper's
straight line and the mast; on the UAV flight, whose velocity is the gradient of its interpolated
path, it departs from the true path by under 2 cm over 180 s. Algorithms 1-3 keep the measured
positions, as the paper does (Table 2's figures are theirs).

What the folded noise also did: it widened every step's measurement noise (4.9' of azimuth at
700 m), and where the estimators' own motion model is wrong that hid the mismatch. On
``--scenario ais`` the real ship's track (PCHIP through its AIS reports: 6-8 m/s^2 RMS per
axis) is nothing like the 0.3 m/s^2 the scenario tells them, and holding the camera exactly
their position RMSE there grows about threefold (README, "Every ship, and the real UAV"); the
old code with the camera known exactly does the same. That is the motion model's to fix
(``--assume-sigma-acc 3`` brings them back near the old figures), not the camera's to hide.

Without a known velocity (a log whose ``observer.csv`` has no ``vx_mps, vy_mps``: the velocity is
then the gradient of the measured positions, which are the fixes themselves) there is no path to
hold: each fix stands alone and its noise is folded in as before (:attr:`Camera.fold`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.experiments.sea import geometry
from workbench.experiments.sea.estimate import Estimate, from_positions
from workbench.experiments.sea.scenario import SeaData


@dataclass(frozen=True)
class Camera:
    """Where an estimator puts the camera and what it knows of it, per step."""

    path: np.ndarray      # (T, 2) the camera in the estimator's frame: the dead-reckoned path d (or the fixes)
    offset: np.ndarray    # (T, 2) c^: the offset's estimate from the fixes up to each step (0 when folded)
    variance: np.ndarray  # (T,) var(c^) per axis, m^2 (0 when folded)
    fold: float           # the camera's variance per axis folded into each step's angle noise, m^2

    @property
    def offset_model(self) -> bool:
        """The camera held as one offset (the platform's velocity known), not folded in."""
        return self.fold == 0.0


def dead_reckoning(data: SeaData) -> np.ndarray:
    """The platform's path from its start, ``(T, 2)``: the trapezoidal integral of its velocity."""
    v = np.asarray(data.observer_velocity, float)
    d = np.zeros_like(v)
    d[1:] = np.cumsum(0.5 * data.dt * (v[1:] + v[:-1]), axis=0)
    return d


def fixes(data: SeaData) -> Camera:
    """The camera at each step's fix, its noise folded into the angles' (the model before the offset)."""
    T = data.steps
    return Camera(np.asarray(data.observer_meas, float), np.zeros((T, 2)), np.zeros(T), data.sigma_observer**2)


def camera(data: SeaData) -> Camera:
    """The run's camera model: the offset's causal estimates on the dead-reckoned path where the
    platform's velocity is known (``data.velocity_known``), else the fixes with their noise folded
    in (:func:`fixes`)."""
    T = data.steps
    if not data.velocity_known:
        return fixes(data)
    d = dead_reckoning(data)
    n = np.arange(1, T + 1)
    offset = np.cumsum(data.observer_meas - d, axis=0) / n[:, None]
    return Camera(d, offset, data.sigma_observer**2 / n, 0.0)


def relative(name: str, data: SeaData, cam: Camera, position: np.ndarray, upto: np.ndarray | int, *,
             covariance: np.ndarray | None = None, state_cov: np.ndarray | None = None,
             forecast: np.ndarray | None = None, **kw) -> Estimate:
    """An estimate made in the estimator's frame (the camera at ``cam.path``) as the workbench's.

    ``upto`` is, per step (or one for all), the last step whose fix the estimate has seen: the
    offset ``c^`` of that step is added to the position (and the forecasts made at that step)
    and its variance to the position's covariance. The angles and range are the relative
    position's from ``cam.path``. With the fixes folded in (no known velocity) nothing moves and
    the angles are :func:`.estimate.from_positions`'s, as before.
    """
    position = np.asarray(position, float)
    if not cam.offset_model:
        return from_positions(name, data, position, covariance=covariance, state_cov=state_cov,
                              forecast=forecast, **kw)
    idx = np.broadcast_to(np.asarray(upto, int), (data.steps,))
    off, var = cam.offset[idx], cam.variance[idx]
    alpha, beta = geometry.angles(position, cam.path, data.course, data.height)
    rng = np.hypot(*(position - cam.path).T)
    if covariance is not None:
        covariance = covariance + var[:, None, None] * np.eye(2)
    if state_cov is not None:
        state_cov = state_cov.copy()
        state_cov[:, :2, :2] += var[:, None, None] * np.eye(2)
    if forecast is not None:
        forecast = forecast + off[:, None, :]
    return Estimate(name=name, position=position + off, alpha=alpha, beta=beta, range=rng,
                    covariance=covariance, state_cov=state_cov, forecast=forecast, **kw)
