"""GTSAM baseline: a constant-velocity target smoothed from azimuth/elevation factors.

Variables per step k: target position ``P(k)`` and velocity ``V(k)`` (Point3, held at sea
level, z = 0). Factors:

* **Motion**: the continuous white-noise-acceleration model with spectral density
  ``q = sigma_acc^2 dt`` (same velocity-increment variance as the simulation's discrete
  model, whose Q is singular and so cannot weight a factor). Linear in the four variables
  ``P(k), V(k), P(k+1), V(k+1)``; Python GTSAM builds JacobianFactors of at most three keys,
  so the four-key block is summed from three-key HessianFactors, converted to a
  JacobianFactor and wrapped in a ``LinearContainerFactor`` (exact for vector-valued
  variables). Built in C++: no Python callback in the optimiser's loop.
* **Camera**: a ``TriangulationFactorCal3_S2``: a fixed unit-focal pinhole at height h on the
  platform's dead-reckoned path (:mod:`.observer`), yawed to the measured azimuth, so the
  measurement is ``(0, tan beta~)`` and its covariance is the angle noise mapped through
  ``d(u, v)/d(alpha, beta) = diag(-1, 1/cos^2 beta)``.
* Priors: ``V(0)`` zero with ``prior_speed`` per axis, z pinned for every variable.

**The camera's offset.** The graph is the platform's frame: the camera's unknown start, which
every fix measures, is not a variable in it, because the angles cannot tell it (moving it and the
whole track together changes no factor), so its estimate, the mean of the fixes less the path,
is added to the track afterwards and its variance to the covariance (:func:`.observer.relative`):
the whole run's fixes for ``gtsam``, those up to the newest step for ``isam2``, up to the step
read for the fixed-lag smoother. That is the graph with the offset as one variable that every
bearing factor shares (``tests/test_sea_observer.py`` builds it, with GTSAM's
``GenericProjectionFactorCal3_S2`` and ``body_P_sensor``, and gets the same track to 0.03 mm),
without T factors on one variable in iSAM2's root. Where the platform's velocity is not known
(:attr:`.observer.Camera.fold`) the camera sits at each fix and its noise is folded into the
angles' (:func:`geometry.effective_noise` at the geometric range (3)-(5)), as before.

``gtsam`` optimises the whole run with Levenberg-Marquardt (a smoother: it uses future
data); ``isam2`` adds one step at a time with QR factorisation (Cholesky fails on this
geometry) and reads its estimate of the newest step: a causal filter-like estimate.
"""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import P, V

from workbench.estimation import kalman
from workbench.experiments.sea import geometry, observer
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData

_CAMERA_IN_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""Columns: camera x (right), y (down), z (forward) in the body frame (x forward, z up)."""
_UNIT_K = gtsam.Cal3_S2(1.0, 1.0, 0.0, 0.0, 0.0)
_Z_PIN = 1e-3
_Z3 = np.zeros(3)
_Z33 = np.zeros((3, 3))


class MotionModel:
    """Whitened CWNA rows for one step, reused for every step (same dt)."""

    def __init__(self, dt: float, sigma_acc: float):
        # a factor needs a full-rank weight: a target simulated without acceleration noise
        # is smoothed with 1e-4 m/s^2 (its effect is far below every other noise here)
        Q = kalman.cv_noise_continuous(dt, max(sigma_acc, 1e-4) ** 2 * dt, axes=1)
        Li = np.linalg.inv(np.linalg.cholesky(Q))
        A = np.zeros((6, 12))  # columns: P(k), V(k), P(k+1), V(k+1), three each
        for ax in range(2):
            R = np.zeros((2, 12))
            R[0, [ax, 3 + ax, 6 + ax]] = [-1.0, -dt, 1.0]
            R[1, [3 + ax, 9 + ax]] = [-1.0, 1.0]
            A[2 * ax:2 * ax + 2] = Li @ R
        A[4, 8] = A[5, 11] = 1.0 / _Z_PIN
        self.G = A.T @ A
        # the 3x3 blocks of G, contiguous, sliced once for all steps
        self.blocks = {(i, j): np.ascontiguousarray(self.G[3 * i:3 * i + 3, 3 * j:3 * j + 3])
                       for i in range(4) for j in range(4)}

    def factor(self, k: int) -> gtsam.LinearContainerFactor:
        keys = [P(k), V(k), P(k + 1), V(k + 1)]
        b = self.blocks
        z, g = _Z33, _Z3
        parts = gtsam.GaussianFactorGraph()
        parts.push_back(gtsam.HessianFactor(keys[0], keys[1], keys[2], b[0, 0], b[0, 1], b[0, 2],
                                            g, b[1, 1], b[1, 2], g, b[2, 2], g, 0.0))
        parts.push_back(gtsam.HessianFactor(keys[0], keys[1], keys[3], z, z, b[0, 3], g, z,
                                            b[1, 3], g, b[3, 3], g, 0.0))
        parts.push_back(gtsam.HessianFactor(keys[2], keys[3], z, b[2, 3], g, z, g, 0.0))
        lin = gtsam.Values()
        for key in keys:
            lin.insert(key, _Z3)
        return gtsam.LinearContainerFactor(gtsam.JacobianFactor(gtsam.HessianFactor(parts)), lin)


def camera_noise(data: SeaData, cam: observer.Camera | None = None) -> np.ndarray:
    """Covariance ``(T, 2, 2)`` of each step's measurement ``(0, tan beta~)``.

    The angle noise ``diag(sa^2, sb^2)`` (with the camera's folded in where it is not held as an
    offset, :attr:`.observer.Camera.fold`, at the geometric position (3)-(5), elevation floored
    at 3 sigma_beta), mapped through ``d(u, v)/d(alpha, beta) = diag(-1, 1/cos^2 beta~)``; NaN
    where the object is unseen.
    """
    cam = observer.camera(data) if cam is None else cam
    b = data.beta_meas
    floor = np.maximum(b, 3.0 * data.sigma_beta)
    guess, _ = geometry.position(data.alpha_meas, floor, cam.path, data.course, data.height)
    R = geometry.effective_noise(guess, cam.path, data.height, data.sigma_alpha,
                                 data.sigma_beta, np.sqrt(cam.fold))
    d = np.stack([np.full_like(b, -1.0), 1.0 / np.cos(b) ** 2], axis=-1)
    return d[:, :, None] * R * d[:, None, :]


def camera_rotations(yaw: np.ndarray) -> np.ndarray:
    """The camera's orientation ``(..., 3, 3)`` yawed to ``yaw`` (course plus measured azimuth):
    ``Rz(yaw) @ _CAMERA_IN_BODY``, for every step at once."""
    c, s = np.cos(yaw), np.sin(yaw)
    Rz = np.zeros(np.shape(yaw) + (3, 3))
    Rz[..., 0, 0], Rz[..., 0, 1], Rz[..., 1, 0], Rz[..., 1, 1], Rz[..., 2, 2] = c, -s, s, c, 1.0
    return Rz @ _CAMERA_IN_BODY


def camera_factor(data: SeaData, k: int, robust: bool, cov: np.ndarray | None = None,
                  cam: observer.Camera | None = None, rotation: np.ndarray | None = None) -> gtsam.NonlinearFactor:
    """The azimuth/elevation measurement of step k as a fixed-camera projection factor, the
    camera at ``cam.path[k]`` (:func:`.observer.camera`, computed here if not given).

    ``cov`` is the measurement covariance (:func:`camera_noise`) and ``rotation`` the camera's
    orientation (:func:`camera_rotations`), computed here if not given.
    """
    cam = observer.camera(data) if cam is None else cam
    b = data.beta_meas[k]
    o = cam.path[k]
    if rotation is None:
        rotation = camera_rotations(np.asarray(data.course[k] + data.alpha_meas[k], float))
    pinhole = gtsam.PinholeCameraCal3_S2(gtsam.Pose3(gtsam.Rot3(rotation), np.array([o[0], o[1], data.height])),
                                         _UNIT_K)
    if cov is None:
        cov = camera_noise(data, cam)[k]
    noise = gtsam.noiseModel.Gaussian.Covariance(cov)
    if robust:
        noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(1.345),
                                               noise)
    return gtsam.TriangulationFactorCal3_S2(pinhole, np.array([0.0, np.tan(b)]), noise, P(k))


def _priors(cfg: SeaConfig, k: int) -> list[gtsam.NonlinearFactor]:
    """Zero velocity with ``prior_speed`` per axis at the first step; z pinned (x, y free)."""
    big = 1e6
    return [
        gtsam.PriorFactorPoint3(V(k), np.zeros(3), gtsam.noiseModel.Diagonal.Sigmas(
            np.array([cfg.prior_speed, cfg.prior_speed, _Z_PIN]))),
        gtsam.PriorFactorPoint3(P(k), np.zeros(3), gtsam.noiseModel.Diagonal.Sigmas(
            np.array([big, big, _Z_PIN]))),
    ]


def _initial_track(data: SeaData, cam: observer.Camera) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities to start LM, in the camera's frame (``cam.path``): geometric
    where seen, a fitted line elsewhere."""
    beta = np.maximum(data.beta_meas, 3.0 * data.sigma_beta)
    xy, _ = geometry.position(data.alpha_meas, beta, cam.path, data.course, data.height)
    ok = np.isfinite(xy[:, 0])
    A = np.stack([np.ones(ok.sum()), data.t[ok]], axis=1)
    coef, *_ = np.linalg.lstsq(A, xy[ok], rcond=None)
    line = coef[0] + data.t[:, None] * coef[1]
    pos = np.where(ok[:, None], xy, line)
    return pos, np.broadcast_to(coef[1], pos.shape)


_MOVES: dict[tuple[float, float], list[gtsam.LinearContainerFactor]] = {}
"""The motion factors by ``(dt, sigma_acc)``, steps 0, 1, ... (:func:`motion_factors`)."""
_MOVES_KEPT = 4


def motion_factors(dt: float, sigma_acc: float, steps: int) -> list[gtsam.LinearContainerFactor]:
    """The motion factors of steps ``0 .. steps - 1``, built once per process for each ``(dt,
    sigma_acc)`` and reused by every run (a factor is immutable: graphs and iSAM2 share it). Each
    costs 60 us to build in Python (three HessianFactors summed into a JacobianFactor): 43 ms of a
    721-step run's 0.1 s, paid again in every Monte Carlo run before this cache. The last
    :data:`_MOVES_KEPT` models are kept (a sweep over ``sigma_acc`` moves on)."""
    key = (float(dt), float(sigma_acc))
    moves = _MOVES.pop(key, None)
    if moves is None:
        moves = []
    if len(moves) < steps:
        motion = MotionModel(dt, sigma_acc)
        moves = moves + [motion.factor(k) for k in range(len(moves), steps)]
    _MOVES[key] = moves  # (re)inserted last: the oldest model is the first dropped
    while len(_MOVES) > _MOVES_KEPT:
        _MOVES.pop(next(iter(_MOVES)))
    return moves[:steps]


class FactorSet:
    """The run's factors, built once and shared by ``gtsam``, ``isam2`` and the fixed-lag smoother
    (same data, same graph), in the frame of the camera's model ``observer`` (:mod:`.observer`),
    and the track to start from (``initial``: positions, velocities)."""

    def __init__(self, data: SeaData, cfg: SeaConfig):
        self.observer = observer.camera(data)
        cov = camera_noise(data, self.observer)
        rot = camera_rotations(np.broadcast_to(data.course, data.alpha_meas.shape) + data.alpha_meas)
        self.camera = [camera_factor(data, k, cfg.robust, cov[k], self.observer, rot[k]) if data.seen[k] else None
                       for k in range(data.steps)]
        self.moves = motion_factors(data.dt, data.sigma_acc, data.steps - 1)
        self.initial = _initial_track(data, self.observer)


def _point(xy: np.ndarray) -> np.ndarray:
    return np.array([xy[0], xy[1], 0.0])


def batch(data: SeaData, cfg: SeaConfig, covariances: bool = False,
          factors: FactorSet | None = None) -> Estimate:
    """Levenberg-Marquardt over the whole run (the smoother)."""
    T = data.steps
    factors = factors or FactorSet(data, cfg)
    graph = gtsam.NonlinearFactorGraph()
    init = gtsam.Values()
    for f in _priors(cfg, 0):
        graph.add(f)
    pos, vel = factors.initial
    for k in range(T):
        if factors.camera[k] is not None:
            graph.add(factors.camera[k])
        if k + 1 < T:
            graph.add(factors.moves[k])
        init.insert(P(k), _point(pos[k]))
        init.insert(V(k), _point(vel[k]))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(100)
    result = gtsam.LevenbergMarquardtOptimizer(graph, init, params).optimize()
    points = gtsam.utilities.extractPoint3(result)  # in key order: P(0..T-1), then V(0..T-1)
    X, Vel = points[:T, :2], points[T:2 * T, :2]
    cov = marginal_covariances(graph, result, T) if covariances else None
    # every step has seen every fix: the offset from all of them
    return observer.relative("gtsam", data, factors.observer, X, T - 1, velocity=Vel, covariance=cov)


def marginal_covariances(graph: gtsam.NonlinearFactorGraph, result: gtsam.Values, steps: int) -> np.ndarray:
    """The (x, y) marginal covariance of every ``P(k)`` at the solution, ``(steps, 2, 2)``.

    GTSAM's ``Marginals`` (a multifrontal Cholesky of the information matrix): 14 ms on a paper
    run. Where that factorisation fails (an ill-conditioned geometry: ``IndeterminantLinearSystem``)
    an iSAM2 with QR seeded at the solution gives the same marginals, 2.6 times slower (37 ms).
    Measured on 30 paper and 5 AIS runs: Cholesky never failed, and its marginals are the QR ones
    to 1e-6 of the standard deviations (``tests/test_sea_smoother.py``).
    """
    try:
        marginals = gtsam.Marginals(graph, result)
        return np.array([marginals.marginalCovariance(P(k))[:2, :2] for k in range(steps)])
    except RuntimeError:
        return marginal_covariances_qr(graph, result, steps)


def marginal_covariances_qr(graph: gtsam.NonlinearFactorGraph, result: gtsam.Values, steps: int) -> np.ndarray:
    """:func:`marginal_covariances` by an iSAM2 with QR factorisation seeded at the solution."""
    qr = gtsam.ISAM2Params()
    qr.setFactorization("QR")
    isam = gtsam.ISAM2(qr)
    isam.update(graph, result)
    return np.array([isam.marginalCovariance(P(k))[:2, :2] for k in range(steps)])


RELINEARIZE = (1.0, 1.0)
"""iSAM2 relinearisation thresholds of positions (m) and velocities (m/s)."""
WILDFIRE = 0.1
"""iSAM2 back-substitution stops where a clique's solution moved less than this (m, m/s);
the newest step sits in the root clique and is always solved exactly."""


def isam2_params() -> gtsam.ISAM2Params:
    """iSAM2 settings: QR, relinearise at ``RELINEARIZE`` (m, m/s), back-substitute to ``WILDFIRE``.

    QR because Cholesky fails on this ill-conditioned geometry. The thresholds decide how
    much of the past is refactorised per step: each new bearing moves the whole past track
    (the range is learnt slowly), so at a 0.1 threshold most of the track was relinearised at
    every step (O(T^2) in all) and the back-substitution ran down the whole chain. A
    linearisation point 1 m off in x and y errs by 0.65' of azimuth and 0.04' of elevation at
    the closest 70 m of the paper's run, less further out; velocities enter only the linear
    motion factors. With the camera held as an offset (:mod:`.observer`) the measurement's
    noise is the camera's 0.88' alone, but a step is linearised at its prediction, centimetres
    from where it ends while the object is close. Measured on six seeded paper runs, the newest
    step's mean distance from the causal MAP (LM to convergence over the run so far) at
    30, 40, 50, 60, 70 s: 0.033, 0.038, 0.044, 0.017, 0.002 m with 1 m / 1 m/s (the newest's
    own sigma there 4.2, 2.6, 1.5, 0.8, 0.3 m); 0.014 ... 0.002 m with 0.3 at 2.3 times the
    time; 0.007 ... 0.001 m with 0.1 at 4.3 times (``tests/test_sea_smoother.py``).
    Relinearisation is checked only where the update touched the tree (the partial check).
    """
    params = gtsam.ISAM2Params()
    params.setFactorization("QR")
    params.relinearizeSkip = 1
    thresholds = gtsam.ISAM2ThresholdMap()
    thresholds.insert(("p", np.full(3, RELINEARIZE[0])))
    thresholds.insert(("v", np.full(3, RELINEARIZE[1])))
    params.setRelinearizeThreshold(thresholds)
    params.setOptimizationParams(gtsam.ISAM2GaussNewtonParams(WILDFIRE))
    params.enablePartialRelinearizationCheck = True
    params.evaluateNonlinearError = False
    return params


def step(data: SeaData, cfg: SeaConfig, factors: FactorSet, k: int, started: bool, start: np.ndarray,
         p: np.ndarray | None, v: np.ndarray | None) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values] | None:
    """Step k's new factors and values for an online smoother: at the first seen step the
    priors and the geometric ``start`` (None before it); after it, the motion factor and the
    prediction from the last estimate ``p, v``; and the camera factor where seen."""
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    if not started:
        if not data.seen[k]:
            return None
        for f in _priors(cfg, k):
            graph.add(f)
        values.insert(P(k), _point(start[k]))
        values.insert(V(k), np.zeros(3))
    else:
        graph.add(factors.moves[k - 1])
        values.insert(P(k), p + data.dt * v)
        values.insert(V(k), v)
    if factors.camera[k] is not None:
        graph.add(factors.camera[k])
    return graph, values


def incremental(data: SeaData, cfg: SeaConfig, covariances: bool = False,
                factors: FactorSet | None = None) -> Estimate:
    """iSAM2, one step per update; the newest step's estimate is recorded (causal)."""
    T, dt, L = data.steps, data.dt, cfg.horizon
    factors = factors or FactorSet(data, cfg)
    params = isam2_params()
    isam = gtsam.ISAM2(params)
    X = np.full((T, 2), np.nan)
    Vel = np.full((T, 2), np.nan)
    cov = np.full((T, 2, 2), np.nan) if covariances else None
    pos0, _ = factors.initial
    p = v = None
    started = False
    for k in range(T):
        new = step(data, cfg, factors, k, started, pos0, p, v)
        if new is None:
            continue
        started = True
        isam.update(*new)
        p = isam.calculateEstimatePoint3(P(k))
        v = isam.calculateEstimatePoint3(V(k))
        X[k], Vel[k] = p[:2], v[:2]
        if covariances:
            cov[k] = isam.marginalCovariance(P(k))[:2, :2]
    steps = np.arange(1, L + 1)[None, :, None] * dt
    forecast = X[:, None, :] + steps * Vel[:, None, :]
    return observer.relative("isam2", data, factors.observer, X, np.arange(T), velocity=Vel, covariance=cov,
                             forecast=forecast)
