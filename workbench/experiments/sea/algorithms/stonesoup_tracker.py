"""Stone Soup's Kalman filters on the sea data: an existing tracking library dropped in as a
plugin (entry points ``sea.stonesoup-ekf`` and ``sea.stonesoup-ukf``; the optional extra
``pip install 'workbench[stonesoup]'``).

Everything is Stone Soup's own: the state ``(x, vx, y, vy, z, vz)`` under a
``CombinedLinearGaussianTransitionModel`` of three ``ConstantVelocity`` models (z held at sea
level with a negligible noise), the measurement model ``CartesianToElevationBearing`` of a
sensor at the measured camera position and height (``translation_offset``) turned to the
course (``rotation_offset``), and its Extended or Unscented predictor and updater. The
workbench only converts: the paper's angles are Stone Soup's ``(elevation, bearing) = (-beta,
alpha)`` (elevation is up, beta is down), the horizontal acceleration noise enters as the
continuous model's ``q = sigma_acc^2 dt`` (the same velocity increment per step as the
simulation's discrete model), and the camera is the workbench's EKF's (:mod:`.observer`): the
sensor rides the platform's dead-reckoned path and the offset its fixes give is added to the
track (where the platform's velocity is not known, the sensor sits at each fix and its noise is
folded into the detection's at the prediction, :func:`geometry.effective_noise`). The first seen
step starts the track from (3)-(5) (:func:`ekf.initial_state`).
"""

from __future__ import annotations

import datetime

import numpy as np
from stonesoup.models.measurement.nonlinear import CartesianToElevationBearing
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.predictor.kalman import ExtendedKalmanPredictor, UnscentedKalmanPredictor
from stonesoup.types.detection import Detection
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.state import GaussianState
from stonesoup.updater.kalman import ExtendedKalmanUpdater, UnscentedKalmanUpdater

from workbench.core.estimator import estimator
from workbench.experiments.sea import geometry, observer
from workbench.experiments.sea.algorithms import ekf
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData

XY = [0, 2]          # x, y in Stone Soup's state order
STATE = [0, 2, 1, 3]  # the workbench's (x, y, vx, vy) in Stone Soup's order
Z_SIGMA = 1e-6       # the sea level (m): z and vz held at zero


def track(data: SeaData, cfg: SeaConfig, kind: str = "ukf", name: str = "stonesoup-ukf") -> Estimate:
    """Filter the run with Stone Soup's EKF (``kind="ekf"``) or UKF; positions, covariances."""
    T, dt = data.steps, data.dt
    q = max(data.sigma_acc, 1e-4) ** 2 * dt
    transition = CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(q), ConstantVelocity(q), ConstantVelocity(Z_SIGMA**2)])
    Predictor, Updater = ((ExtendedKalmanPredictor, ExtendedKalmanUpdater) if kind == "ekf"
                          else (UnscentedKalmanPredictor, UnscentedKalmanUpdater))
    predictor = Predictor(transition)
    start = datetime.datetime(2016, 1, 12)
    X = np.full((T, 4), np.nan)
    P = np.full((T, 4, 4), np.nan)
    cam = observer.camera(data)
    state = None
    for k in range(T):
        when = start + datetime.timedelta(seconds=float(data.t[k]))
        if state is not None:
            state = predictor.predict(state, timestamp=when)
        if data.seen[k]:
            if state is None:
                x0, p0 = ekf.initial_state(data, k, cfg.prior_speed, cam)
                mean, cov = np.zeros(6), np.diag(np.full(6, Z_SIGMA**2))
                mean[STATE] = x0
                cov[np.ix_(STATE, STATE)] = p0
                state = GaussianState(mean[:, None], cov, timestamp=when)
            else:
                o = cam.path[k]
                R = geometry.effective_noise(np.asarray(state.state_vector[XY], float).ravel(), o, data.height,
                                             data.sigma_alpha, data.sigma_beta, np.sqrt(cam.fold))
                noise = np.array([[R[1, 1], -R[0, 1]], [-R[0, 1], R[0, 0]]])  # (elevation, bearing)
                model = CartesianToElevationBearing(
                    ndim_state=6, mapping=(0, 2, 4), noise_covar=noise,
                    translation_offset=np.array([[o[0]], [o[1]], [data.height]]),
                    rotation_offset=np.array([[0.0], [0.0], [data.course[k]]]))
                z = Detection(np.array([[-data.beta_meas[k]], [data.alpha_meas[k]]]), timestamp=when,
                              measurement_model=model)
                state = Updater(model).update(SingleHypothesis(state, z))
        if state is not None:
            X[k] = np.asarray(state.state_vector, float).ravel()[STATE]
            P[k] = np.asarray(state.covar, float)[np.ix_(STATE, STATE)]
    P = (P + np.swapaxes(P, 1, 2)) / 2
    return observer.relative(name, data, cam, X[:, :2].copy(), np.arange(T), velocity=X[:, 2:].copy(),
                             covariance=P[:, :2, :2].copy(), state_cov=P)


@estimator(description="Stone Soup's UnscentedKalmanUpdater with CartesianToElevationBearing (a library tracker)",
           causal=True, covariances=True)
def stonesoup_ukf(data: SeaData, cfg: SeaConfig) -> Estimate:
    return track(data, cfg, "ukf", "stonesoup-ukf")


@estimator(description="Stone Soup's ExtendedKalmanUpdater with CartesianToElevationBearing (a library tracker)",
           causal=True, covariances=True)
def stonesoup_ekf(data: SeaData, cfg: SeaConfig) -> Estimate:
    return track(data, cfg, "ekf", "stonesoup-ekf")
