"""The GTSAM baseline: a Pose2 / Point2 factor graph with bearing factors.

Keyframes are the bearing epochs (plus one at least every ``keyframe_every`` seconds, so
a stretch without landmarks still has poses). Between keyframes the odometry is integrated
with the same model (7)-(8) as the filter, in the earlier keyframe's frame, and enters as
a ``BetweenFactorPose2`` whose covariance is rotated into GTSAM's tangent space (Pose2's
errors live in the body frame of the later pose). Each bearing is a
``BearingFactor2D(pose, point, Rot2, sigma_theta)``. A landmark enters the graph only once
two of its rays meet with ``graph_parallax`` or more (held-back factors are added then): a
landmark seen from one place only leaves the linear system indeterminate.

* ``isam2``: iSAM2 (QR factorisation, relinearisation threshold ``relin_threshold``) updated
  at every keyframe; its newest pose at that time is what a causal estimator knows, so it
  is comparable to the filter's.
* ``gtsam-batch``: Levenberg-Marquardt over the whole run, started from dead reckoning
  (and landmarks triangulated from it), marginal covariances for every pose.

Covariances are returned in the world frame (``x, y, phi``) like the filter's:
``C_world = J C_body J'``, ``J = diag(R(phi), 1)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.estimation.angles import wrap
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData
from workbench.experiments.omni.triangulation import rays

FLOOR = 1e-10  # variance floor: a one-step odometry covariance is rank 2


def _to_body(cov: np.ndarray, heading: float) -> np.ndarray:
    c, s = math.cos(heading), math.sin(heading)
    j = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return j @ cov @ j.T


def to_world(cov: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Pose2 tangent-space covariances ``(E, 3, 3)`` to world ``x, y, phi``."""
    c, s = np.cos(heading), np.sin(heading)
    j = np.zeros((len(heading), 3, 3))
    j[:, 0, 0], j[:, 0, 1], j[:, 1, 0], j[:, 1, 1], j[:, 2, 2] = c, -s, s, c, 1.0
    return j @ cov @ j.transpose(0, 2, 1)


@dataclass
class Keyframes:
    """The graph's skeleton: keyframe steps, odometry between them, bearings per keyframe."""

    steps: np.ndarray
    between: list[tuple[gtsam.Pose2, np.ndarray]]
    bearings: list[tuple[np.ndarray, np.ndarray]]
    dead_reckoning: np.ndarray


def keyframes(data: OmniData, cfg: OmniConfig) -> Keyframes:
    epochs = dict(data.epochs())
    marks = set(epochs)
    marks.add(0)
    # at least one keyframe every keyframe_every seconds
    t = data.t
    last = 0.0
    for k in range(len(t)):
        if k in marks:
            last = t[k]
        elif t[k] - last >= cfg.keyframe_every:
            marks.add(k)
            last = t[k]
    steps = np.array(sorted(marks), int)
    between = []
    zero = np.zeros(3)
    dt = data.dt
    for a, b in zip(steps[:-1], steps[1:], strict=True):
        poses, covs, _ = data.motion.propagate(zero, np.zeros((3, 3)), data.controls[a:b], dt[a:b])
        rel = poses[-1]
        cov = _to_body(covs[-1], rel[2]) + FLOOR * np.eye(3)
        between.append((gtsam.Pose2(rel[0], rel[1], rel[2]), cov))
    empty = (np.zeros(0, int), np.zeros(0))
    bearings = [(data.meas_lm[epochs[s]], data.meas_bearing[epochs[s]]) if s in epochs else empty
                for s in steps]
    dr = data.motion.integrate(data.start, data.controls, dt)
    return Keyframes(steps, between, bearings, dr[steps])


def _parallax_ok(pi: np.ndarray, bi: float, pj: np.ndarray, bj: float, min_parallax: float
                 ) -> np.ndarray | None:
    """The two rays' intersection if they meet in front of both with enough parallax."""
    if abs(wrap((pj[2] + bj) - (pi[2] + bi))) < min_parallax:
        return None
    point, si, sj = rays(np.array([*pi, *pj, bi, bj]))
    if not (si[0] > 0 and sj[0] > 0):
        return None
    return point[0]


class _Landmarks:
    """Held-back bearings per landmark until two rays give a good intersection."""

    def __init__(self, n: int, sigma: float, min_parallax: float):
        self.obs: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        self.inserted = np.zeros(n, bool)
        self.noise = gtsam.noiseModel.Isotropic.Sigma(1, sigma)
        self.min_parallax = min_parallax

    def factor(self, kf: int, lm: int, bearing: float) -> gtsam.BearingFactor2D:
        return gtsam.BearingFactor2D(X(kf), L(lm), gtsam.Rot2.fromAngle(bearing), self.noise)

    def try_insert(self, lm: int, pose_of) -> np.ndarray | None:
        """Triangulate from the first sighting and the newest; the point if accepted."""
        first, newest = self.obs[lm][0], self.obs[lm][-1]
        return _parallax_ok(pose_of(first[0]), first[1], pose_of(newest[0]), newest[1], self.min_parallax)


def _noise(cov: np.ndarray):
    return gtsam.noiseModel.Gaussian.Covariance(cov)


def _prior(data: OmniData) -> gtsam.PriorFactorPose2:
    cov = data.start_cov + np.diag([1e-6, 1e-6, 1e-8])
    return gtsam.PriorFactorPose2(X(0), gtsam.Pose2(*data.start), _noise(cov))


def _pose(p: gtsam.Pose2) -> np.ndarray:
    return np.array([p.x(), p.y(), p.theta()])


def isam2(data: OmniData, cfg: OmniConfig, kf: Keyframes | None = None, map_every: float = math.inf
          ) -> SlamEstimate:
    """iSAM2, one update per keyframe; the newest pose and its marginal at every keyframe.

    The map (means and marginals) is read every ``map_every`` seconds and at the end:
    landmark marginals cost more than the update itself, so Monte Carlo runs read it once.
    """
    kf = kf or keyframes(data, cfg)
    params = gtsam.ISAM2Params()
    params.setFactorization("QR")
    params.setRelinearizeThreshold(cfg.relin_threshold)
    params.enablePartialRelinearizationCheck = True
    # stop back-substitution where the change is under 0.01 (default 0.001): 10 % faster,
    # the same answer to 0.1 mm here
    params.setOptimizationParams(gtsam.ISAM2GaussNewtonParams(0.01))
    isam = gtsam.ISAM2(params)
    n_lm, E = len(data.landmarks), len(kf.steps)
    marks = _Landmarks(n_lm, data.sigma_bearing, math.radians(cfg.graph_parallax_deg))
    poses = np.empty((E, 3))
    covs = np.empty((E, 3, 3))
    first_seen = np.full(n_lm, -1)
    init_step = np.full(n_lm, -1)
    known: dict[int, np.ndarray] = {}
    map_steps, map_mean, map_cov = [], [], []
    last_map = -math.inf
    current = gtsam.Pose2(*data.start)
    for e in range(E):
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        if e == 0:
            graph.add(_prior(data))
        else:
            odo, cov = kf.between[e - 1]
            graph.add(gtsam.BetweenFactorPose2(X(e - 1), X(e), odo, _noise(cov)))
            current = current.compose(odo)
        values.insert(X(e), current)
        known[e] = _pose(current)
        lms, bearings = kf.bearings[e]
        for lm, b in zip(lms, bearings, strict=True):
            lm, b = int(lm), float(b)
            if first_seen[lm] < 0:
                first_seen[lm] = kf.steps[e]
            if marks.inserted[lm]:
                graph.add(marks.factor(e, lm, b))
                continue
            marks.obs[lm].append((e, b))
            if len(marks.obs[lm]) < 2:
                continue
            point = marks.try_insert(lm, known.__getitem__)
            if point is None:
                continue
            values.insert(L(lm), point)
            for k, bk in marks.obs[lm]:
                graph.add(marks.factor(k, lm, bk))
            marks.inserted[lm] = True
            init_step[lm] = kf.steps[e]
        isam.update(graph, values)
        current = isam.calculateEstimatePose2(X(e))
        poses[e] = _pose(current)
        covs[e] = isam.marginalCovariance(X(e))
        known[e] = poses[e]
        if data.t[kf.steps[e]] - last_map >= map_every or e == E - 1:
            last_map = data.t[kf.steps[e]]
            mean = np.full((n_lm, 2), np.nan)
            cov = np.full((n_lm, 2, 2), np.nan)
            for lm in np.flatnonzero(marks.inserted):
                mean[lm] = isam.calculateEstimatePoint2(L(int(lm)))
                cov[lm] = isam.marginalCovariance(L(int(lm)))
            map_steps.append(kf.steps[e])
            map_mean.append(mean)
            map_cov.append(cov)
    return SlamEstimate("isam2", kf.steps.copy(), poses, to_world(covs, poses[:, 2]), np.array(map_steps),
                        np.array(map_mean), np.array(map_cov), first_seen, init_step)


def batch(data: OmniData, cfg: OmniConfig, kf: Keyframes | None = None) -> SlamEstimate:
    """Levenberg-Marquardt over the whole run from dead reckoning; marginals for every pose."""
    kf = kf or keyframes(data, cfg)
    n_lm, E = len(data.landmarks), len(kf.steps)
    marks = _Landmarks(n_lm, data.sigma_bearing, math.radians(cfg.graph_parallax_deg))
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    graph.add(_prior(data))
    for e in range(E):
        values.insert(X(e), gtsam.Pose2(*kf.dead_reckoning[e]))
        if e:
            odo, cov = kf.between[e - 1]
            graph.add(gtsam.BetweenFactorPose2(X(e - 1), X(e), odo, _noise(cov)))
    first_seen = np.full(n_lm, -1)
    init_step = np.full(n_lm, -1)
    for e in range(E):
        lms, bearings = kf.bearings[e]
        for lm, b in zip(lms, bearings, strict=True):
            lm, b = int(lm), float(b)
            if first_seen[lm] < 0:
                first_seen[lm] = kf.steps[e]
            if marks.inserted[lm]:
                graph.add(marks.factor(e, lm, b))
                continue
            marks.obs[lm].append((e, b))
            if len(marks.obs[lm]) < 2:
                continue
            point = marks.try_insert(lm, lambda k: kf.dead_reckoning[k])
            if point is None:
                continue
            values.insert(L(lm), point)
            for k, bk in marks.obs[lm]:
                graph.add(marks.factor(k, lm, bk))
            marks.inserted[lm] = True
            init_step[lm] = kf.steps[e]
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(100)
    params.setRelativeErrorTol(1e-7)
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    poses = np.array([_pose(result.atPose2(X(e))) for e in range(E)])
    try:
        marginals = gtsam.Marginals(graph, result)
        covs = np.array([marginals.marginalCovariance(X(e)) for e in range(E)])
        lm_cov = np.full((n_lm, 2, 2), np.nan)
        for lm in np.flatnonzero(marks.inserted):
            lm_cov[lm] = marginals.marginalCovariance(L(int(lm)))
    except RuntimeError:
        covs = np.full((E, 3, 3), np.nan)
        lm_cov = np.full((n_lm, 2, 2), np.nan)
    mean = np.full((n_lm, 2), np.nan)
    for lm in np.flatnonzero(marks.inserted):
        mean[lm] = result.atPoint2(L(int(lm)))
    return SlamEstimate("gtsam-batch", kf.steps.copy(), poses, to_world(covs, poses[:, 2]),
                        np.array([kf.steps[-1]]), mean[None], lm_cov[None], first_seen, init_step)
