"""The factor graph's skeleton: keyframes (the bearing epochs, and one at least every
``keyframe_every`` seconds), the odometry integrated between them with the filter's model (7)-(8)
as ``BetweenFactorPose2`` factors, their covariances rotated into GTSAM's tangent space (Pose2's
errors live in the body frame of the later pose), and the world-frame covariances
``C_world = J C_body J'``, ``J = diag(R(phi), 1)``."""

from __future__ import annotations

import math
from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import X

from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData, keyframe_steps

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
    sigmas: list[np.ndarray] | None = None  # each keyframe's bearings' sigmas (rad), beside ``bearings``

    def sigma(self, e: int) -> np.ndarray:
        """Keyframe ``e``'s bearings' sigmas."""
        return self.sigmas[e]


def keyframes(data: OmniData, cfg: OmniConfig) -> Keyframes:
    """The graph's skeleton on the dataset's grid (:func:`.scenario.keyframe_steps`)."""
    epochs = dict(data.epochs())
    steps = data.grid if data.grid is not None else keyframe_steps(data, cfg.keyframe_every)
    between = []
    zero = np.zeros(3)
    dt = data.dt
    for a, b in zip(steps[:-1], steps[1:], strict=True):
        poses, covs, _ = data.motion.propagate(zero, np.zeros((3, 3)), *data.odometry(a, b))
        rel = poses[-1]
        cov = _to_body(covs[-1], rel[2]) + FLOOR * np.eye(3)
        between.append((gtsam.Pose2(rel[0], rel[1], rel[2]), cov))
    empty = (np.zeros(0, int), np.zeros(0))
    bearings = [(data.meas_lm[epochs[s]], data.meas_bearing[epochs[s]]) if s in epochs else empty
                for s in steps]
    sigmas = [data.bearing_sigma(epochs[s]) if s in epochs else np.zeros(0) for s in steps]
    dr = data.motion.integrate(data.start, data.controls, dt)
    return Keyframes(steps, between, bearings, dr[steps], sigmas)


def _noise(cov: np.ndarray):
    return gtsam.noiseModel.Gaussian.Covariance(cov)


def _prior(data: OmniData) -> gtsam.PriorFactorPose2:
    cov = data.start_cov + np.diag([1e-6, 1e-6, 1e-8])
    return gtsam.PriorFactorPose2(X(0), gtsam.Pose2(*data.start), _noise(cov))


def _pose(p: gtsam.Pose2) -> np.ndarray:
    return np.array([p.x(), p.y(), p.theta()])


def poses_of(values: gtsam.Values, count: int) -> np.ndarray:
    """The keyframe poses ``X(0) .. X(count - 1)`` of ``values`` as ``(count, 3)`` x, y, heading, read
    in one call (``gtsam.utilities.extractPose2``: every Pose2 in key order; the graphs' only Pose2
    are their keyframes, inserted from ``X(0)`` on without a gap), the same bits as one
    ``atPose2`` per pose (20x faster at 1,347 poses)."""
    out = gtsam.utilities.extractPose2(values)[:count]
    if len(out) < count:
        raise KeyError(f"{count} keyframe poses asked of values holding {len(out)}")
    return out


def compose_cov(pose: np.ndarray, cov: np.ndarray, rel: gtsam.Pose2, rel_body: np.ndarray) -> np.ndarray:
    """The world-frame covariance of ``pose (+) rel`` from ``pose``'s ``cov`` and ``rel``'s
    covariance ``rel_body`` (GTSAM's tangent space at the later pose, as the odometry factors
    hold it): first order, ``F cov F' + G C G'`` with ``F`` the composition's Jacobian in the
    earlier pose and ``G = diag(R(phi), 1)`` taking ``rel`` from the earlier pose's frame."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = c * rel.x() - s * rel.y(), s * rel.x() + c * rel.y()
    f = np.array([[1.0, 0.0, -dy], [0.0, 1.0, dx], [0.0, 0.0, 1.0]])
    g = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    rel_earlier = _to_body(rel_body, -rel.theta())
    return f @ cov @ f.T + g @ rel_earlier @ g.T


def _lm_params(iterations: int) -> gtsam.LevenbergMarquardtParams:
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(iterations)
    params.setRelativeErrorTol(1e-7 if iterations >= 100 else 1e-5)
    return params


def _odometry_graph(data: OmniData, kf: Keyframes) -> gtsam.NonlinearFactorGraph:
    """The start's prior and the odometry between keyframes: every graph's first factors."""
    graph = gtsam.NonlinearFactorGraph()
    graph.add(_prior(data))
    for e, (odo, cov) in enumerate(kf.between, start=1):
        graph.add(gtsam.BetweenFactorPose2(X(e - 1), X(e), odo, _noise(cov)))
    return graph
