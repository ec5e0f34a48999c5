"""A fixed-lag smoother for bearing-only SLAM: GTSAM's ``IncrementalFixedLagSmoother`` on the
same keyframes, odometry and bearing factors as ``isam2`` and ``gtsam-batch`` (:mod:`.graph`),
registered as the plugin ``omni.fixed-lag`` (an entry point, as a user's package would).

Poses older than the lag are marginalised, and so are **landmarks not seen for**
``LANDMARK_LAG`` (120 s, more than the paper's 75 s lap): a landmark's timestamp is renewed at
every update while it was seen within that, so the window holds the last ``lag`` seconds of poses
and the landmarks seen in the last two minutes, and an update costs what that window costs
whatever the log's length (GTSAM's fixed-lag smoothing: Dellaert and Kaess, *Factor Graphs for
Robot Perception*, 2017, sec. 5.3). A landmark re-observed after a lap is still the same variable,
with all it has learnt; one read as it leaves (its mean and marginal then) stays in the map as
read, and seen again later it enters again from two new rays, as a visual-odometry window
re-detects a point. Held-back bearings (``graph_parallax``) are kept only while their keyframe
is in the window: a landmark enters from two in-window rays with the parallax, never from a pose
already marginalised (a factor on a variable that is gone).

Before (until 2026-12), every landmark's timestamp was renewed at every update, so none ever left
and the window grew with the map. On the synthetic 7,000-pose drive (``benchmarks/bench_isam2.py
--log long``) the window now costs 0.63 s against 1.72 s, its newest pose 8.3 m RMSE against 28 m;
the paper's 200 and 500 s runs are unchanged (0.19 and 0.31 m), their landmarks seen again within
the lap.

A landmark's linearisation point is frozen into the marginal once the poses that saw it
leave the window, so it must enter well conditioned: it waits for its first and newest
in-window rays to meet at ``ENTRY_PARALLAX`` bearing sigmas of parallax (15 at the paper's
1 deg, as MRCLAM's graph needs anyway; at least ``graph_parallax``), where a two-ray
triangulation's depth error is about 7 % of the range, inside a bearing factor's linear
range. At the graph's 5 deg (20 %) the short window froze landmarks tens of metres off
(paper simulation, 200 s, lag 5 s: map errors of 20-800 m, pose RMSE 0.8-1.6 m; at 15 deg,
0.14-0.22 m, as the batch smoother's).

Each keyframe's pose is read when it is about to leave the window, ``lag`` seconds after it:
it has seen the data up to ``t + lag`` (a causal system with a fixed delay), so its accuracy
lies between the causal ``isam2`` and the batch ``gtsam-batch``; the last ``lag`` seconds
are read at the end. Covariances are the marginals at that moment (world frame).

The lag (``LAG``, 5 s) is a method: a landmark at 10-20 m gains the 5 deg of parallax the
graph waits for within about a second at 3 m/s, so 5 s holds several of its sightings and a
few seconds of odometry either side, at a delay short next to a 75 s lap. If GTSAM throws on
an update (an indeterminate system), that keyframe's bearings are left out (``failures``).

Robot 5 of MRCLAM turns on the spot at 798 s, and a landmark entered from two keyframes there
made GTSAM throw ("indeterminate linear system"): their rays' 15 sigmas of parallax came from
positions the odometry cannot tell apart. Two keyframes closer than ``BASELINE_SIGMAS`` of the
odometry between them no longer place a landmark, and robot 5 runs (1.4 m RMSE; ``isam2`` 0.43).

Not for MRCLAM as it stands: iSAM2's undamped Gauss-Newton steps run away there after blind
stretches (:class:`.graph._Incremental` says why; ``isam2`` survives by damped LM passes over
the whole graph, which a marginalising window cannot take). Measured on robots 1 and 2: with
5 s the window rarely holds two rays 15 deg apart (4 and 15 landmarks, 2.5 and 3.2 m RMSE, no
better than odometry); with 30 s it runs away (7.7 m to 1e5 m).
"""

from __future__ import annotations

import math

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.core.estimator import RunContext, estimator
from workbench.experiments.omni.algorithms import graph
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData

LAG = 5.0
"""Seconds of data after a keyframe that its estimate waits for."""
ENTRY_PARALLAX = 15.0
"""A landmark enters once two in-window rays meet at this many bearing sigmas of parallax."""
LANDMARK_LAG = 120.0
"""Seconds a landmark stays in the window after its newest bearing."""
BASELINE_SIGMAS = 3.0
"""... and their keyframes are this many sigmas of the odometry between them apart."""


def _params(cfg: OmniConfig) -> gtsam.ISAM2Params:
    """iSAM2's settings in the window: those of the ``isam2`` estimator (QR, its thresholds)."""
    params = gtsam.ISAM2Params()
    params.setFactorization("QR")
    params.setRelinearizeThreshold(cfg.relin_threshold)
    params.enablePartialRelinearizationCheck = True
    params.setOptimizationParams(gtsam.ISAM2GaussNewtonParams(0.01))
    return params


def run(data: OmniData, cfg: OmniConfig, kf: graph.Keyframes, lag: float = LAG, record: bool = False,
        name: str = "fixed-lag") -> SlamEstimate:
    """Smooth the keyframes online with a ``lag``-second window; each read ``lag`` s later."""
    steps = kf.steps
    t = data.t[steps]
    E, n_lm = len(steps), len(data.landmarks)
    fls = gtsam.IncrementalFixedLagSmoother(lag, _params(cfg))
    parallax = max(math.radians(cfg.graph_parallax_deg), ENTRY_PARALLAX * data.sigma_bearing)
    # the position variance the odometry adds from the start to each keyframe: two keyframes closer
    # than BASELINE_SIGMAS of what it adds between them see a landmark from the same place, as far as
    # the data know (a robot turning on the spot: its rays' parallax is noise, and a landmark entered
    # from them sits a few millimetres off the path, an indeterminate system for GTSAM)
    added = np.concatenate([[0.0], np.cumsum([float(np.trace(np.asarray(c)[:2, :2])) for _, c in kf.between])])
    marks = graph._Landmarks(n_lm, data.sigma_bearing, parallax, cfg.huber,
                             baseline=lambda i, j: BASELINE_SIGMAS * math.sqrt(max(added[j] - added[i], 0.0)))
    first_seen, init_step = np.full(n_lm, -1), np.full(n_lm, -1)
    poses, covs = np.full((E, 3), np.nan), np.full((E, 3, 3), np.nan)
    known: dict[int, np.ndarray] = {}       # each keyframe's pose as last estimated
    map_steps, map_mean, map_cov = [], [], []
    last_map = -math.inf
    oldest = 0                              # the oldest keyframe still in the window
    current = gtsam.Pose2(*data.start)
    failures = 0

    def read(j: int) -> None:
        poses[j] = graph._pose(fls.calculateEstimatePose2(X(j)))
        covs[j] = fls.marginalCovariance(X(j))

    seen = np.zeros(n_lm, bool)
    last_seen = np.full(n_lm, -math.inf)   # each landmark's newest bearing in the graph
    stamp = np.full(n_lm, -math.inf)       # its timestamp in the smoother: renewed while seen in LANDMARK_LAG
    left_mean, left_cov = np.full((n_lm, 2), np.nan), np.full((n_lm, 2, 2), np.nan)  # as read when it left

    def leave(lm: int) -> None:
        """A landmark about to be marginalised: read now, kept in the map as read, out of the graph."""
        left_mean[lm] = fls.calculateEstimatePoint2(L(lm))
        left_cov[lm] = fls.marginalCovariance(L(lm))
        marks.inserted[lm] = False
        marks.obs[lm] = []

    def snapshot(e: int, last: bool = False) -> None:
        """The map now (:func:`.graph.read_map`: the marginals of the landmarks seen since the last
        snapshot; every ``graph.MAP_FULL``-th snapshot and the last, all of them)."""
        previous = map_cov[-1] if map_cov else np.full((n_lm, 2, 2), np.nan)
        mean, cov = graph.read_map(np.flatnonzero(marks.inserted).tolist(), previous, seen,
                                   last or len(map_steps) % graph.MAP_FULL == 0,
                                   lambda lm: fls.calculateEstimatePoint2(L(lm)),
                                   lambda lm: fls.marginalCovariance(L(lm)))
        gone = ~marks.inserted & np.isfinite(left_mean[:, 0])
        mean[gone], cov[gone] = left_mean[gone], left_cov[gone]
        map_steps.append(steps[e])
        map_mean.append(mean)
        map_cov.append(cov)

    for e in range(E):
        while t[oldest] < t[e] - lag:       # it leaves with this update: read it now
            read(oldest)
            oldest += 1
        factors, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        if e == 0:
            factors.add(graph._prior(data))
        else:
            odo, cov = kf.between[e - 1]
            factors.add(gtsam.BetweenFactorPose2(X(e - 1), X(e), odo, graph._noise(cov)))
            current = current.compose(odo)
        values.insert(X(e), current)
        known[e] = graph._pose(current)
        lms, bearings = kf.bearings[e]
        seen[lms] = True
        entered = []
        for lm, b, sigma in zip(lms, bearings, kf.sigma(e), strict=True):
            lm, b = int(lm), float(b)
            if first_seen[lm] < 0:
                first_seen[lm] = steps[e]
            if not marks.inserted[lm]:  # held rays of marginalised keyframes cannot take part
                marks.obs[lm] = [(k, bk) for k, bk in marks.obs[lm] if k >= oldest]
            new, point = marks.observe(e, lm, b, known.__getitem__, sigma=float(sigma))
            for f in new:
                factors.add(f)
            if point is not None:
                values.insert(L(lm), point)
                entered.append(lm)
        before = last_seen.copy(), stamp.copy()
        last_seen[[int(lm) for lm in lms if marks.inserted[int(lm)]]] = t[e]   # a factor on it in this update
        renew = np.flatnonzero(marks.inserted & (last_seen >= t[e] - LANDMARK_LAG))
        stamp[renew] = t[e]
        for lm in np.flatnonzero(marks.inserted & (stamp < t[e] - lag)):
            leave(int(lm))   # its timestamp falls behind the window with this update
        stamps = {X(e): float(t[e])}
        stamps.update({L(int(lm)): float(t[e]) for lm in renew})
        try:
            fls.update(factors, values, stamps)
        except RuntimeError:
            # an indeterminate system: this keyframe's bearings (and entries) are left out
            failures += 1
            for lm in entered:
                marks.inserted[lm] = False
            entered = []
            last_seen, stamp = before   # their bearings did not go in
            bare, only = gtsam.NonlinearFactorGraph(), gtsam.Values()
            bare.add(factors.at(0))
            only.insert(X(e), current)
            fls.update(bare, only, {X(e): float(t[e])})
        current = fls.calculateEstimatePose2(X(e))
        known[e] = graph._pose(current)
        for lm in entered:
            init_step[lm] = steps[e]
        if record and t[e] - last_map >= 1.0:
            last_map = t[e]
            snapshot(e)
    for j in range(oldest, E):
        read(j)
    snapshot(E - 1, last=True)
    return SlamEstimate(name, steps.copy(), poses, graph.to_world(covs, poses[:, 2]), np.array(map_steps),
                        np.array(map_mean), np.array(map_cov), first_seen, init_step, failures=failures)


def with_lag(lag: float):
    """The fixed-lag smoother with another lag, as an estimator function (for the API)."""

    @estimator(name=f"fixed-lag-{lag:g}s", description=f"GTSAM fixed-lag smoother, each keyframe read {lag:g} s later",
               causal=True, covariances=True, lag=lag)
    def fixed_lag_at(data: OmniData, cfg: OmniConfig, ctx: RunContext) -> SlamEstimate:
        return run(data, cfg, ctx.shared("keyframes", lambda: graph.keyframes(data, cfg)), lag, ctx.record,
                   f"fixed-lag-{lag:g}s")

    return fixed_lag_at


@estimator(description=f"GTSAM IncrementalFixedLagSmoother, each keyframe read {LAG:g} s later "
           "(online, fixed delay; landmarks kept in the window)", causal=True, covariances=True, lag=LAG)
def fixed_lag(data: OmniData, cfg: OmniConfig, ctx: RunContext) -> SlamEstimate:
    """The fixed-lag smoother on the run's shared keyframes (the ``isam2``/``gtsam-batch`` ones)."""
    return run(data, cfg, ctx.shared("keyframes", lambda: graph.keyframes(data, cfg)), LAG, ctx.record)
