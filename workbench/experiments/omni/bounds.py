"""The omni experiment's Cramér-Rao bounds: how well any estimator could know the vehicle's pose
and the map from the same odometry and bearings (:mod:`workbench.estimation.bounds`).

The model is the estimators' own, at the truth: the odometry (7)-(8) integrated between the
grid's steps into one increment each (:func:`graph.keyframes`: the same covariance the GTSAM
baselines use), its Jacobian taken along the true path; a bearing ``atan2(l - p) - phi`` with
``sigma_bearing`` from each grid step to each landmark it sees; the known start (``start_cov``);
each landmark entering with a weak prior (``LANDMARK_PRIOR``), which only keeps a landmark seen
once from leaving the system indeterminate.

* **Filtering bound** (the causal estimators): the recursion of the posterior bound on the pose
  and the landmarks seen so far, covariance form, one step per grid step (predict with the
  increment, add each landmark when first seen, update with the step's bearings).
* **Smoothing bound** (the smoothers; also a valid, looser limit for a fixed-lag smoother): the
  information of the whole problem at the truth, GTSAM's ``Marginals`` of the Pose2/Point2
  graph built at the true values.
* **Map bound**: each landmark's marginal from all the data (the same for both).
"""

from __future__ import annotations

import math

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.experiments.omni.algorithms import graph
from workbench.experiments.omni.algorithms.graph.marginals import marginal_blocks
from workbench.experiments.omni.scenario import OmniData

LANDMARK_PRIOR = 1.0e3
"""Standard deviation (m) of a landmark's prior when it enters: none to speak of."""
FLOOR = graph.FLOOR



def _truth(data: OmniData, kf: graph.Keyframes) -> np.ndarray:
    """The true poses at the keyframes, the linearisation point of the bounds; across a gap in
    the ground truth (MRCLAM robot 4's Vicon has 2.0 s and 0.55 s gaps) interpolated in time
    (the heading unwrapped), so the bound covers the gap as the errors there are not scored."""
    truth = data.truth[kf.steps].copy()
    ok = np.isfinite(truth).all(axis=1)
    if ok.all() or not ok.any():
        return truth
    t = data.t[kf.steps]
    for j in range(2):
        truth[~ok, j] = np.interp(t[~ok], t[ok], truth[ok, j])
    truth[~ok, 2] = np.interp(t[~ok], t[ok], np.unwrap(truth[ok, 2]))
    return truth

def _increments(data: OmniData, kf: graph.Keyframes) -> tuple[np.ndarray, np.ndarray]:
    """Each grid interval's Jacobian of the next pose in the last one ``A (E-1, 3, 3)`` along the
    true path, and its noise in the world frame ``(E-1, 3, 3)``: the increment's covariance
    (body frame of the later pose in ``kf.between``) turned into the earlier true pose's frame."""
    truth = _truth(data, kf)
    E = len(truth)
    A = np.broadcast_to(np.eye(3), (E - 1, 3, 3)).copy()
    A[:, 0, 2] = -(truth[1:, 1] - truth[:-1, 1])
    A[:, 1, 2] = truth[1:, 0] - truth[:-1, 0]
    noise = np.empty((E - 1, 3, 3))
    for i, (rel, cov) in enumerate(kf.between):
        c, s = math.cos(rel.theta()), math.sin(rel.theta())
        to_body = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        relative = to_body.T @ (cov - FLOOR * np.eye(3)) @ to_body    # in the earlier pose's frame
        c, s = math.cos(truth[i, 2]), math.sin(truth[i, 2])
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        noise[i] = rot @ relative @ rot.T + FLOOR * np.eye(3)
    return A, noise


def filtering(data: OmniData, kf: graph.Keyframes) -> np.ndarray:
    """The filtering bound on the pose at every grid step, world ``x, y, phi``, ``(E, 3, 3)``."""
    truth = _truth(data, kf)
    A, noise = _increments(data, kf)
    P = data.start_cov + np.diag([1e-6, 1e-6, 1e-8])   # as the graph's prior
    slot: dict[int, int] = {}
    out = np.empty((len(truth), 3, 3))
    var = data.sigma_bearing**2
    for e in range(len(truth)):
        if e:
            P[:3, :] = A[e - 1] @ P[:3, :]
            P[:, :3] = P[:, :3] @ A[e - 1].T
            P[:3, :3] += noise[e - 1]
        lms = [int(lm) for lm in kf.bearings[e][0]]
        for lm in dict.fromkeys(lms):
            if lm not in slot:
                slot[lm] = len(P)
                grown = np.zeros((len(P) + 2, len(P) + 2))
                grown[:len(P), :len(P)] = P
                grown[len(P):, len(P):] = LANDMARK_PRIOR**2 * np.eye(2)
                P = grown
        if lms:
            H = np.zeros((len(lms), len(P)))
            d = data.landmarks[lms] - truth[e, :2]
            r2 = np.sum(d**2, axis=1)
            H[:, 0], H[:, 1], H[:, 2] = d[:, 1] / r2, -d[:, 0] / r2, -1.0
            for row, lm in enumerate(lms):
                H[row, slot[lm]:slot[lm] + 2] = -d[row, 1] / r2[row], d[row, 0] / r2[row]
            PH = P @ H.T
            S = H @ PH + (var * np.eye(len(lms)) if data.meas_sigma is None else np.diag(kf.sigma(e) ** 2))
            P = P - PH @ np.linalg.solve(S, PH.T)
            P = 0.5 * (P + P.T)
        out[e] = P[:3, :3]
    return out


def smoothing(data: OmniData, kf: graph.Keyframes) -> tuple[np.ndarray, np.ndarray]:
    """The smoothing bound on the pose at every grid step (world ``x, y, phi``, ``(E, 3, 3)``) and
    on each landmark from all the data (``(N, 2, 2)``, NaN for one never seen): GTSAM's
    marginals of the whole graph at the true values."""
    truth = _truth(data, kf)
    E, N = len(truth), len(data.landmarks)
    g, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    g.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(*truth[0]), gtsam.noiseModel.Gaussian.Covariance(
        data.start_cov + np.diag([1e-6, 1e-6, 1e-8]))))
    for e in range(E):
        values.insert(X(e), gtsam.Pose2(*truth[e]))
        if e:
            rel = gtsam.Pose2(*truth[e - 1]).between(gtsam.Pose2(*truth[e]))
            g.add(gtsam.BetweenFactorPose2(X(e - 1), X(e), rel, gtsam.noiseModel.Gaussian.Covariance(
                kf.between[e - 1][1])))
    noise = gtsam.noiseModel.Isotropic.Sigma(1, data.sigma_bearing)
    seen = np.zeros(N, bool)
    for e in range(E):
        for lm, sigma in zip(kf.bearings[e][0], kf.sigma(e), strict=True):
            lm = int(lm)
            d = data.landmarks[lm] - truth[e, :2]
            own = noise if data.meas_sigma is None else gtsam.noiseModel.Isotropic.Sigma(1, float(sigma))
            g.add(gtsam.BearingFactor2D(X(e), L(lm), gtsam.Rot2(math.atan2(d[1], d[0]) - truth[e, 2]), own))
            seen[lm] = True
    prior = gtsam.noiseModel.Isotropic.Sigma(2, LANDMARK_PRIOR)
    for lm in np.flatnonzero(seen):
        values.insert(L(int(lm)), data.landmarks[lm])
        g.add(gtsam.PriorFactorPoint2(L(int(lm)), data.landmarks[lm], prior))
    marginals = gtsam.Marginals(g, values)
    blocks = marginal_blocks(marginals, [X(e) for e in range(E)] + [L(int(lm)) for lm in np.flatnonzero(seen)])
    poses = np.array(blocks[:E])
    maps = np.full((N, 2, 2), np.nan)
    if seen.any():
        maps[seen] = blocks[E:]
    return graph.to_world(poses, truth[:, 2]), maps


def variances(data: OmniData, kf: graph.Keyframes, delays: set[float]) -> dict:
    """What a run's summary keeps: per delay (0: filtering; anything else: smoothing) the bound on
    position (``var x + var y``, m^2) and heading (rad^2) at every grid step, and each landmark's
    (``var x + var y``) from all the data."""
    out: dict = {}
    smooth, maps = smoothing(data, kf)
    for d in delays:
        P = filtering(data, kf) if d == 0 else smooth
        out[d] = {"position": P[:, 0, 0] + P[:, 1, 1], "heading": P[:, 2, 2]}
    out["map"] = maps[:, 0, 0] + maps[:, 1, 1]
    return out
