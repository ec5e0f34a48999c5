"""EKF on the constant-velocity target model: the nonlinear-filtering approach of the sea
paper's reference [8], on the same measurements as algorithms 1-3.

State ``[x, y, vx, vy]``; prediction with the simulation's own discrete white-noise
acceleration model; update with ``(alpha, beta)`` from (1)-(2) seen from the camera as
:mod:`.observer` holds it: the filter runs in the platform's frame, the camera on its
dead-reckoned path, and adds the camera's start as the fixes so far give it (their mean, its
variance ``sigma_o^2 / (k + 1)`` on the position): the same filter as one with the start in its
state (``tests/test_sea_observer.py``). The first seen step initialises the position by (3)-(5)
with its linearised covariance and the velocity as zero with ``prior_speed`` per axis. An
optional chi-square gate (``ekf_gate`` = its probability, 0 = off) drops outlying measurements
(the impulse case).

Consistency (measured, paper scenario, seeds 0..99): the ANEES is 3.89, inside the 95 % band
[3.46, 4.57]; the radial pair (range, range rate) 1.92, the lateral 1.97; the mean radial error
-3.9 m over the first 10 s and -0.8 m over the next 10 (the estimate too far: the elevation's
range nonlinearity, ``(sigma_beta / beta)^2`` of the range at the first updates). Before, with
each fix's noise folded into R (:func:`geometry.effective_noise`), the ANEES was 4.96, above the
band, all of the excess radial (2.91; -10 m and -5 m): with the bearings about 5 times noisier
at 700 m, the range leant more on the elevation and was learnt more slowly. It was read then as
the nonlinearity's alone; that no observer noise gave 3.91 was the hint.
"""

from __future__ import annotations

import math

import numpy as np

from workbench.estimation import kalman
from workbench.estimation.consistency import Innovations
from workbench.experiments.sea import geometry, observer
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData


def initial_state(data: SeaData, k: int, prior_speed: float,
                  cam: observer.Camera | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Position from (3)-(5) at step k, seen from the camera at ``cam.path[k]``, with covariance
    ``G R G'`` plus the camera's folded variance; zero velocity. Default: the step's fix, its noise
    folded in (:func:`.observer.fixes`: a position in the sea's frame, for anyone's filter); the
    EKF passes its :func:`.observer.camera` (the platform's frame, nothing folded)."""
    cam = observer.fixes(data) if cam is None else cam
    a, b = data.alpha_meas[k], data.beta_meas[k]
    xy, d = geometry.position(a, b, cam.path[k], data.course[k], data.height)
    bearing = a + data.course[k]
    u = np.array([np.cos(bearing), np.sin(bearing)])
    dd_db = -data.height / np.sin(b) ** 2
    G = np.stack([d * np.array([-u[1], u[0]]), dd_db * u], axis=1)  # d xy / d (alpha, beta)
    R = np.diag([data.sigma_alpha**2, data.sigma_beta**2])
    P = np.zeros((4, 4))
    P[:2, :2] = G @ R @ G.T + cam.fold * np.eye(2)
    P[2:, 2:] = prior_speed**2 * np.eye(2)
    return np.concatenate([xy, [0.0, 0.0]]), P


_PI, _TWO_PI = math.pi, 2.0 * math.pi


def _measure(ex: float, ey: float, course: float, height: float) -> tuple[float, float, np.ndarray]:
    """Azimuth and elevation (1)-(2) of the relative position ``(ex, ey)`` and their Jacobian
    ``d(alpha, beta)/d(x, y)``: :func:`.geometry.angles` and :func:`.geometry.angle_jacobian` for
    one point, in scalars."""
    c, s = math.cos(course), math.sin(course)
    k2 = ex * ex + ey * ey
    k = math.sqrt(k2)
    g = -height / ((k2 + height * height) * k)
    J = np.array([[-ey / k2, ex / k2], [g * ex, g * ey]])
    return math.atan2(-ex * s + ey * c, ex * c + ey * s), math.atan2(height, k), J


def estimate(data: SeaData, cfg: SeaConfig) -> Estimate:
    """Filter the run; returns positions, covariances, NIS-gated flags and l-step forecasts.

    The measurement model is evaluated in scalars (:func:`_measure`: (1)-(2) and their Jacobian,
    ``geometry.angles`` and ``angle_jacobian`` written out for one point), and the update in the
    Joseph form with the 2x2 innovation covariance inverted in closed form: the same equations as
    :func:`.kalman.update` (``tests/test_sea_math.py`` holds them equal), a third of the time."""
    T, dt = data.steps, data.dt
    F = kalman.cv_transition(dt)
    Q = kalman.cv_noise_discrete(dt, data.sigma_acc)
    gated = cfg.ekf_gate > 0
    # the chi-square quantile of 2 degrees of freedom in closed form: -2 ln(1 - p)
    gate = -2.0 * np.log1p(-cfg.ekf_gate)
    X = np.full((T, 4), np.nan)
    Ps = np.full((T, 4, 4), np.nan)
    rows: list[tuple[float, np.ndarray, np.ndarray, np.ndarray, bool]] = []  # the innovations: (t, nu, S, R, kept)
    cam = observer.camera(data)
    fold = float(cam.fold)
    R_angles = np.diag([data.sigma_alpha**2, data.sigma_beta**2])
    path, course, h = cam.path.tolist(), np.asarray(data.course, float).tolist(), float(data.height)
    a_meas, b_meas = data.alpha_meas.tolist(), data.beta_meas.tolist()
    seen, t = data.seen.tolist(), data.t.tolist()
    eye = np.eye(4)
    x = P = None
    for k in range(T):
        if x is not None:
            x = F @ x
            P = F @ P @ F.T + Q
            P = 0.5 * (P + P.T)
        if seen[k]:
            if x is None:
                x, P = initial_state(data, k, cfg.prior_speed, cam)
            else:
                ox, oy = path[k]
                ha, hb, J = _measure(x[0] - ox, x[1] - oy, course[k], h)
                R = R_angles if fold == 0.0 else R_angles + fold * (J @ J.T)
                nu = np.array([_PI - (_PI - (a_meas[k] - ha)) % _TWO_PI, b_meas[k] - hb])  # wrapped as angles.wrap
                PHt = P[:, :2] @ J.T                      # P H' with H = [J, 0]
                S = J @ PHt[:2] + R
                det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
                Si = np.array([[S[1, 1], -S[0, 1]], [-S[1, 0], S[0, 0]]]) / det
                if not gated or nu @ Si @ nu <= gate:
                    K = PHt @ Si
                    ikh = eye.copy()
                    ikh[:, :2] -= K @ J
                    x = x + K @ nu
                    P = ikh @ P @ ikh.T + K @ R @ K.T
                    P = 0.5 * (P + P.T)
                    rows.append((t[k], nu, S, R, True))
                else:  # gated: the innovation it was judged on is kept for the diagnosis
                    rows.append((t[k], nu, S, R, False))
        if x is not None:
            X[k], Ps[k] = x, P
    # l-step forecasts: F^l x (positions only)
    L = cfg.horizon
    Fl = np.stack([np.linalg.matrix_power(F, l)[:2] for l in range(1, L + 1)])  # (L, 2, 4)
    forecast = np.einsum("lij,tj->tli", Fl, X)
    innovations = Innovations(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]).reshape(-1, 2),
                              np.array([r[2] for r in rows]).reshape(-1, 2, 2), np.array([r[4] for r in rows], bool),
                              np.array([r[3] for r in rows]).reshape(-1, 2, 2), cfg.ekf_gate if gated else None)
    return observer.relative("ekf", data, cam, X[:, :2].copy(), np.arange(T), covariance=Ps[:, :2, :2].copy(),
                             state_cov=Ps, velocity=X[:, 2:].copy(), forecast=forecast, innovations=innovations)
