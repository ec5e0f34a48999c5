"""The GTSAM baseline: a Pose2 / Point2 factor graph with bearing factors.

Keyframes are the bearing epochs (plus one at least every ``keyframe_every`` seconds, so
a stretch without landmarks still has poses). Between keyframes the odometry is integrated
with the same model (7)-(8) as the filter, in the earlier keyframe's frame, and enters as
a ``BetweenFactorPose2`` whose covariance is rotated into GTSAM's tangent space (Pose2's
errors live in the body frame of the later pose). Each bearing is a
``BearingFactor2D(pose, point, Rot2, sigma_theta)``, Huber-robust beyond ``huber`` sigmas
where that is set. A landmark enters the graph only once two of its rays meet with
``graph_parallax`` or more (held-back factors are added then): a landmark seen from one
place only leaves the linear system indeterminate.

* ``isam2``: iSAM2 (QR factorisation, relinearisation threshold ``relin_threshold``) updated
  at every keyframe; its newest pose at that time is what a causal estimator knows, so it
  is comparable to the filter's. A damped Levenberg-Marquardt pass over the graph so far only
  where an update runs away; with ``lm_every > 0`` also every ``lm_every`` seconds and whenever
  a landmark enters (:class:`_Incremental` says why that is no longer the default).
* ``gtsam-batch``: Levenberg-Marquardt over the whole run, marginal covariances for every
  pose. Started from the starts ``--batch-starts`` names in turn (dead reckoning with
  landmarks triangulated from it, iSAM2's or the EKF's answer, or with ``lm_every > 0`` the
  graph grown keyframe by keyframe with those LM passes) until one's fit passes its test.

Covariances are returned in the world frame (``x, y, phi``) like the filter's:
``C_world = J C_body J'``, ``J = diag(R(phi), 1)``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.estimation import outliers
from workbench.estimation.angles import wrap
from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni import residuals
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData, keyframe_steps
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


def _parallax_ok(pi: np.ndarray, bi: float, pj: np.ndarray, bj: float, min_parallax: float
                 ) -> np.ndarray | None:
    """The two rays' intersection if they meet in front of both with enough parallax."""
    if abs(wrap((pj[2] + bj) - (pi[2] + bi))) < min_parallax:
        return None
    point, si, sj = rays(np.array([*pi, *pj, bi, bj]))
    if not (si[0] > 0 and sj[0] > 0):
        return None
    return point[0]


def bearing_noise(sigma: float, huber: float = 0.0) -> gtsam.noiseModel.Base:
    """The bearing factors' noise: Gaussian, or Huber-robust beyond ``huber`` sigmas (> 0)."""
    base = gtsam.noiseModel.Isotropic.Sigma(1, sigma)
    if huber > 0.0:
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(huber), base)
    return base


class _Landmarks:
    """Held-back bearings per landmark until two rays give a good intersection."""

    def __init__(self, n: int, sigma: float, min_parallax: float, huber: float = 0.0):
        self.obs: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        self.inserted = np.zeros(n, bool)
        self.outliers: list[tuple[int, int]] = []
        self.noise = bearing_noise(sigma, huber)
        self.min_parallax = min_parallax
        self.default, self.huber = sigma, huber
        self.own: dict[tuple[int, int], float] = {}  # (keyframe, landmark) -> its bearing's own sigma
        self.noises: dict[float, gtsam.noiseModel.Base] = {}

    def factor(self, kf: int, lm: int, bearing: float) -> gtsam.BearingFactor2D:
        sigma = self.own.get((kf, lm))
        noise = self.noise if sigma is None else self.noises.setdefault(sigma, bearing_noise(sigma, self.huber))
        return gtsam.BearingFactor2D(X(kf), L(lm), gtsam.Rot2.fromAngle(bearing), noise)

    def observe(self, e: int, lm: int, bearing: float, pose_of, preset: np.ndarray | None = None,
                tolerance: float = math.inf, sigma: float | None = None
                ) -> tuple[list[gtsam.BearingFactor2D], np.ndarray | None]:
        """Take bearing ``bearing`` of ``lm`` at keyframe ``e``. Returns the factors to add now
        (this one if ``lm`` is in the graph; every held one if it enters now) and, if it enters
        now, its starting point (``preset`` where given, else :meth:`try_insert`). With a finite
        ``tolerance`` (rad), once the first and the newest ray meet with parallax, the held rays
        are checked against each other (:func:`consensus`): those that disagree are left out,
        listed in ``self.outliers`` as ``(keyframe, lm)``. ``sigma``: the bearing's own, where it is
        not the default."""
        if sigma is not None and sigma != self.default:
            self.own[(e, lm)] = float(sigma)
        if self.inserted[lm]:
            return [self.factor(e, lm, bearing)], None
        self.obs[lm].append((e, bearing))
        if len(self.obs[lm]) < (3 if preset is None and math.isfinite(tolerance) else 2):
            return [], None  # with a gate, a landmark waits for a third ray: two always meet
        if preset is None and math.isfinite(tolerance) and len(self.obs[lm]) >= 3:
            (first, b_first), (newest, b_newest) = self.obs[lm][0], self.obs[lm][-1]
            if _parallax_ok(pose_of(first), b_first, pose_of(newest), b_newest, self.min_parallax) is None:
                return [], None  # not yet: the first and the newest ray decide when, as without the check
            poses = np.array([pose_of(k) for k, _ in self.obs[lm]])
            found = consensus(poses, np.array([b for _, b in self.obs[lm]]), tolerance, self.min_parallax)
            if found is None:
                return [], None
            point, inlier = found
            self.outliers.extend((k, lm) for (k, _), ok in zip(self.obs[lm], inlier, strict=True) if not ok)
            self.obs[lm] = [o for o, ok in zip(self.obs[lm], inlier, strict=True) if ok]
        else:
            point = preset if preset is not None else self.try_insert(lm, pose_of)
        if point is None:
            return [], None
        self.inserted[lm] = True
        return [self.factor(k, lm, bk) for k, bk in self.obs[lm]], point

    def try_insert(self, lm: int, pose_of) -> np.ndarray | None:
        """The landmark's starting point, or None while the first sighting's and the newest
        one's rays do not meet in front of both with ``min_parallax``. The two rays' meeting
        point is refined by least squares over every held ray (:func:`refine`)."""
        first, newest = self.obs[lm][0], self.obs[lm][-1]
        point = _parallax_ok(pose_of(first[0]), first[1], pose_of(newest[0]), newest[1], self.min_parallax)
        if point is None or len(self.obs[lm]) < 3:
            return point
        poses = np.array([pose_of(k) for k, _ in self.obs[lm]])
        return refine(point, poses, np.array([b for _, b in self.obs[lm]]))


def consensus(poses: np.ndarray, bearings: np.ndarray, tolerance: float, min_parallax: float,
              samples: int = 12) -> tuple[np.ndarray, np.ndarray] | None:
    """A landmark's starting point agreed by most of its held rays, and which rays agree.

    Candidates are the meeting points of pairs among ``samples`` rays spread over the held ones
    (the first and the newest always among them) that meet in front of both with
    ``min_parallax``; a ray agrees with a candidate when its bearing is within ``tolerance``
    of it. The candidate with the most agreeing rays (then the smallest squared residual) is
    refined on those (:func:`refine`). None while no pair qualifies or fewer than three rays
    agree (so a pair of rays alone never places a landmark against the rest).

    Why: the rays held until a landmark has parallax can span minutes; one taken from a pose
    the odometry got wrong (MRCLAM robot 5 at 600 s, heading 20-36 deg off) met the first
    sighting's 5 m from the landmark, behind the views of a hundred rays held between them
    (their residuals 180 deg); the graph took all of them and LM stalled at 2800 times the
    cost it reaches from the truth (measured).
    """
    k = len(poses)
    pick = np.unique(np.linspace(0, k - 1, min(k, samples)).round().astype(int))
    best: tuple[int, float, np.ndarray] | None = None
    for a in range(len(pick)):
        for b in range(a + 1, len(pick)):
            i, j = pick[a], pick[b]
            point = _parallax_ok(poses[i], bearings[i], poses[j], bearings[j], min_parallax)
            if point is None:
                continue
            r = np.abs(_residuals(point, poses, bearings))
            agree = r < tolerance
            score = (int(agree.sum()), -float(np.sum(r[agree] ** 2)))
            if best is None or score > best[:2]:
                best = (*score, point)
    if best is None or best[0] < 3:
        return None
    point = best[2]
    agree = np.abs(_residuals(point, poses, bearings)) < tolerance
    point = refine(point, poses[agree], bearings[agree])
    agree = np.abs(_residuals(point, poses, bearings)) < tolerance
    return (point, agree) if agree.sum() >= 3 else None


def _residuals(point: np.ndarray, poses: np.ndarray, bearings: np.ndarray) -> np.ndarray:
    d = point[None, :] - poses[:, :2]
    return wrap(bearings - (np.arctan2(d[:, 1], d[:, 0]) - poses[:, 2]))


def refine(point: np.ndarray, poses: np.ndarray, bearings: np.ndarray, iterations: int = 10) -> np.ndarray:
    """Gauss-Newton (step halved while the squared bearing error grows) on the landmark alone:
    the point that best explains ``bearings`` from ``poses (K, 3)`` held fixed, started at
    ``point``. ``point`` itself where the answer is behind any view or more than twice as far
    from the newest view (near-parallel rays let the least squares slide off along them).

    Why: two rays with a few degrees of parallax taken from poses that are themselves off
    can put a landmark tens of metres from where the other held rays say (paper simulation,
    seed 4: 13 m and 25 m at 16-22 m range), and iSAM2's undamped first step from there can
    run away (metres of pose error, then a landmark at 1e97 m).
    """
    def cost(x: np.ndarray) -> float:
        return float(np.sum(_residuals(x, poses, bearings) ** 2))

    x, c = point.astype(float).copy(), cost(point)
    for _ in range(iterations):
        d = x[None, :] - poses[:, :2]
        q = np.einsum("ki,ki->k", d, d)
        r = _residuals(x, poses, bearings)
        J = np.stack([-d[:, 1] / q, d[:, 0] / q], axis=1)
        try:
            dx = np.linalg.solve(J.T @ J, J.T @ r)
        except np.linalg.LinAlgError:
            break
        for _ in range(10):
            trial = x + dx
            c_trial = cost(trial)
            if np.isfinite(c_trial) and c_trial <= c:
                break
            dx = dx / 2
        else:
            break
        x, c = trial, c_trial
        if np.hypot(*dx) < 1e-6 * (1.0 + np.sqrt(q.min())):
            break
    d = x[None, :] - poses[:, :2]
    ahead = np.cos(np.arctan2(d[:, 1], d[:, 0]) - poses[:, 2] - bearings) > 0.0
    near = np.hypot(*(x - poses[-1, :2])) <= 2.0 * np.hypot(*(point - poses[-1, :2]))
    return x if (ahead.all() and near and np.isfinite(x).all()) else point


def _noise(cov: np.ndarray):
    return gtsam.noiseModel.Gaussian.Covariance(cov)


def _prior(data: OmniData) -> gtsam.PriorFactorPose2:
    cov = data.start_cov + np.diag([1e-6, 1e-6, 1e-8])
    return gtsam.PriorFactorPose2(X(0), gtsam.Pose2(*data.start), _noise(cov))


def _pose(p: gtsam.Pose2) -> np.ndarray:
    return np.array([p.x(), p.y(), p.theta()])


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


JUMP_POSITION = 2.0
JUMP_HEADING = math.radians(10.0)


def _jumped(predicted: gtsam.Pose2, estimate: gtsam.Pose2) -> bool:
    """Whether an update moved the newest pose implausibly far from its odometry prediction."""
    d = predicted.between(estimate)
    return math.hypot(d.x(), d.y()) > JUMP_POSITION or abs(d.theta()) > JUMP_HEADING


def _lm_params(iterations: int) -> gtsam.LevenbergMarquardtParams:
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(iterations)
    params.setRelativeErrorTol(1e-7 if iterations >= 100 else 1e-5)
    return params


class _Incremental:
    """The graph grown one keyframe at a time, landmarks held back until triangulated;
    optionally iSAM2 updated at every keyframe (``solver``) and a Levenberg-Marquardt pass
    over the graph so far every ``lm_every`` seconds and whenever a landmark enters.

    Why the LM passes (``spec/omni.md`` leaves this open; MRCLAM needs them): iSAM2 takes one
    undamped Gauss-Newton step per update, relinearising only what moved past a threshold.
    After a blind stretch of tens of seconds the heading is off by 10-20 deg, a landmark
    enters from rays whose poses carry that drift, and on a bearing-only graph with
    landmarks a few metres away and stiff (sub-millimetre) odometry those steps can
    oscillate and run away: on robot 1, 50 deg of heading error within ten keyframes, then
    metres, then GTSAM's "indeterminate linear system". Whether it does depends on the
    relinearisation and back-substitution thresholds in no useful pattern (measured). LM is
    damped and converges from the same start. Its start for the poses added since the last
    pass is the last pass's answer carried on with the odometry (not iSAM2's estimate
    meanwhile, which may have run away); iSAM2 is then rebuilt, linearised at LM's answer.
    Between passes iSAM2 runs as usual, so its newest pose stays the causal estimate.

    Why ``lm_every = 0`` is now the default everywhere (issue 36): each pass is a solve of the
    whole graph so far, so a log twice as long cost 4.4x (a 14,000-pose drive: 24 of its 29 s in
    passes, measured). The run-aways the passes stopped came from the gate and the held rays,
    which followed the chain of the last pass carried on by the odometry: without passes that
    chain drifts, good bearings fail the gate, and landmarks enter from stale poses (MRCLAM 6
    robot 3: 2,516 bearings gated, 26 s of passes at run-aways). Without passes the graph
    follows iSAM2 itself (:meth:`_follow`, :meth:`_pose_of`, :meth:`_point`): the gate predicts
    from iSAM2's newest pose and its marginal, the landmark's estimate and marginal (read, at
    most every ``POINT_REFRESH`` s, for a bearing that fails without it), and held rays are
    placed from iSAM2's current poses. MRCLAM 6
    robots 1-5 then end as close to the truth as with passes or closer (iSAM2 0.27-0.49 m,
    the batch unchanged to 1 cm) in 2-4x less time; a pass is left only where an update runs
    away (:func:`_jumped`) or throws. ``ISAM2DoglegParams`` (a trust region inside iSAM2) was
    tried instead: its updates cost 12x the Gauss-Newton ones on robot 3 (15 of 19 s), its step
    reading the whole tree's gradient, so it is not used.

    Whenever iSAM2 throws (an indeterminate system: the symptom of a run-away, in the paper's
    simulation too, where it ended some seeds' runs), there is an LM pass at once and the
    solver is rebuilt from it; if that throws too, the keyframe's bearings are left out
    (counted in ``failures``; the landmarks it completed wait for a later sighting).
    """

    def __init__(self, data: OmniData, cfg: OmniConfig, kf: Keyframes, solver: bool = True):
        self.data, self.cfg, self.kf = data, cfg, kf
        self.params = gtsam.ISAM2Params()
        self.params.setFactorization("QR")
        self.params.setRelinearizeThreshold(cfg.relin_threshold)
        self.params.enablePartialRelinearizationCheck = True
        # stop back-substitution where the change is under 0.01 (default 0.001): 10 % faster,
        # the same answer to 0.1 mm here
        self.params.setOptimizationParams(gtsam.ISAM2GaussNewtonParams(0.01))
        self.isam = gtsam.ISAM2(self.params) if solver else None
        n_lm = len(data.landmarks)
        self.marks = _Landmarks(n_lm, data.sigma_bearing, math.radians(cfg.graph_parallax_deg), cfg.huber)
        self.first_seen = np.full(n_lm, -1)
        self.init_step = np.full(n_lm, -1)
        self.known: dict[int, np.ndarray] = {}   # each pose as last estimated
        self.points: dict[int, np.ndarray] = {}  # each landmark in the graph, as last estimated
        self.everything = gtsam.NonlinearFactorGraph()
        self.start = gtsam.Values()              # the next LM pass's start
        self.chain = gtsam.Pose2(*data.start)    # the last LM answer carried on with the odometry
        self.current = gtsam.Pose2(*data.start)
        self.failures = 0
        self.passes = 0
        self.last_pass = 0.0
        self.done = -1
        # the bearing gate (``nis_gate`` > 0): the chain's pose covariance (world frame) since
        # the last LM pass, each landmark's marginal at that pass, the bearings left out
        self.gate = chi2_quantile(cfg.nis_gate, 1) if cfg.nis_gate > 0.0 else math.inf
        self.threshold = gate_of(cfg)
        if outlier_rate(cfg) > 0.0:  # the outlier model's gate instead (:func:`gate_of`); finite: gating on
            self.gate = float(self.threshold(data.sigma_bearing ** 2))
        self.chain_cov = np.asarray(data.start_cov, float).copy()
        self.point_cov: dict[int, np.ndarray] = {}
        self.rejected: set[tuple[int, int]] = set()
        # without LM passes the gate and the held rays follow iSAM2's own estimate (:meth:`_follow`)
        self.follow = solver and cfg.lm_every == 0.0
        self.point_read: dict[int, float] = {}   # when each landmark's marginal was last read (follow)
        self.newest_cov: np.ndarray | None = None
        self.refreshed = -math.inf

    def step(self, e: int) -> np.ndarray:
        """Add keyframe ``e`` (its odometry, its bearings, the landmarks it completes); update.
        Returns the newest pose's estimate."""
        kf, marks, cfg = self.kf, self.marks, self.cfg
        self.newest_cov = None
        motion, pose_value = gtsam.NonlinearFactorGraph(), gtsam.Values()
        if e == 0:
            motion.add(_prior(self.data))
        else:
            odo, cov = kf.between[e - 1]
            motion.add(gtsam.BetweenFactorPose2(X(e - 1), X(e), odo, _noise(cov)))
            self.current = self.current.compose(odo)
            self.chain_cov = compose_cov(_pose(self.chain), self.chain_cov, odo, cov)
            self.chain = self.chain.compose(odo)
        pose_value.insert(X(e), self.current)
        self.known[e] = _pose(self.current)
        sights, points = gtsam.NonlinearFactorGraph(), gtsam.Values()
        entered = []
        lms, bearings = kf.bearings[e]
        for lm, b, sigma in zip(lms, bearings, kf.sigma(e), strict=True):
            lm, b, sigma = int(lm), float(b), float(sigma)
            if self.first_seen[lm] < 0:
                self.first_seen[lm] = kf.steps[e]
            if marks.inserted[lm] and not self._consistent(lm, b, sigma):
                self.rejected.add((e, lm))
                continue
            factors, point = marks.observe(e, lm, b, self._pose_of, tolerance=self._tolerance(), sigma=sigma)
            for factor in factors:
                sights.add(factor)
            if point is not None:
                points.insert(L(lm), point)
                self.points[lm] = point
                entered.append(lm)
        self.rejected.update(marks.outliers)
        marks.outliers.clear()
        graph = gtsam.NonlinearFactorGraph(motion)
        graph.push_back(sights)
        values = gtsam.Values(pose_value)
        values.insert(points)
        predicted = self.current
        threw = self.isam is not None and not self._update(graph, values)
        if not threw and self.isam is not None and _jumped(predicted, self.current):
            # iSAM2 takes one undamped Gauss-Newton step per update; a newest pose thrown
            # metres or tens of degrees from its prediction is such a step running away:
            # a damped LM pass over the graph so far brings it back
            threw = True
            self.runaways += 1
        kept = self.everything.size()
        self.everything.push_back(graph)
        self.start.insert(values)
        self.start.update(X(e), self.chain)
        self.done = e
        t = self.data.t[kf.steps[e]]
        if threw or (cfg.lm_every > 0.0 and (entered or t - self.last_pass >= cfg.lm_every)):
            self.last_pass = t
            if not self._pass(e) and self.isam is not None:
                # leave this keyframe's bearings out (the landmarks it completed wait for a
                # later sighting) and try once more; past that, the solver is dropped and the
                # estimate is the LM passes' carried on with the odometry
                self.failures += 1
                for lm in entered:
                    marks.inserted[lm] = False
                    del self.points[lm]
                    self.start.erase(L(lm))
                entered = []
                everything = gtsam.NonlinearFactorGraph()
                for i in range(kept):
                    everything.add(self.everything.at(i))
                everything.push_back(motion)
                self.everything = everything
                if not self._pass(e):
                    self.isam = None
        if self.isam is None:
            self.current = self.chain
        elif self.follow and not threw:
            self._follow(e)
            if t - self.refreshed >= self.START_REFRESH:
                # the next pass's start: iSAM2's estimate now, at most this old at a run-away
                # (its poses as first predicted, never corrected since, took LM 50 iterations)
                self.start, self.refreshed = self.isam.calculateEstimate(), t
        self.known[e] = _pose(self.current)
        for lm in entered:
            self.init_step[lm] = kf.steps[e]
        return self.known[e]

    runaways = 0

    START_REFRESH = 20.0
    """s: how often, following iSAM2, the start of a pass at a run-away is taken from its estimate
    (0.6 ms for 2,900 variables: a cost over the log of its length times its length over 20 s,
    0.05 s on a 14,000-pose drive)."""

    POINT_REFRESH = 10.0
    """s: how old a landmark's marginal may be before the gate reads it again from iSAM2 (follow)."""

    def _pose_of(self, k: int) -> np.ndarray:
        """Keyframe ``k``'s pose as the graph holds it now: iSAM2's estimate where it follows
        iSAM2 (a held ray's pose corrected since it was newest), else as last estimated."""
        if self.follow and self.isam is not None and k <= self.done and self.isam.valueExists(X(k)):
            return _pose(self.isam.calculateEstimatePose2(X(k)))
        return self.known[k]

    def _follow(self, e: int) -> None:
        """After an update without LM passes: the gate's prediction starts from iSAM2's newest
        pose and its marginal (not the odometry chain since the last pass, which never comes)."""
        self.chain = self.current
        cov = _marginal(self.isam, X(e), 3)
        self.newest_cov = cov
        if np.isfinite(cov).all():
            self.chain_cov = to_world(cov[None], np.array([self.current.theta()]))[0]

    def _holds(self, lm: int) -> bool:
        """Whether the graph follows iSAM2 and iSAM2 holds landmark ``lm``."""
        return self.follow and self.isam is not None and self.isam.valueExists(L(lm))

    def _point(self, lm: int) -> tuple[np.ndarray, Callable[[], np.ndarray | None]]:
        """A landmark's point for the gate and how to get its marginal: where the graph follows
        iSAM2 (and iSAM2 holds it), iSAM2's estimate now and its marginal as read at most
        ``POINT_REFRESH`` s ago (read only when asked: a Bayes-tree walk); else the point it entered
        at or the last LM pass's, with that pass's marginal."""
        if not self._holds(lm):
            return self.points[lm], lambda: self.point_cov.get(lm)  # (or it entered at this keyframe)

        def marginal() -> np.ndarray | None:
            t = float(self.data.t[self.kf.steps[self.done]]) if self.done >= 0 else 0.0
            if t - self.point_read.get(lm, -math.inf) >= self.POINT_REFRESH:
                cov = _marginal(self.isam, L(lm), 2)
                if np.isfinite(cov).all():
                    self.point_cov[lm] = cov
                self.point_read[lm] = t
            return self.point_cov.get(lm)

        return np.asarray(self.isam.calculateEstimatePoint2(L(lm)), float), marginal

    def _tolerance(self) -> float:
        """How far (rad) a held ray may be from a landmark's starting point (:func:`consensus`):
        the gate's number of sigmas of the bearing noise and the current heading's uncertainty
        (the held rays' poses, corrected by LM passes since, are no less certain)."""
        if not math.isfinite(self.gate):
            return math.inf
        s = self.data.sigma_bearing ** 2 + self.chain_cov[2, 2]
        return math.sqrt(max(float(self.threshold(s)), 0.0) * s)

    def _consistent(self, lm: int, bearing: float, sigma: float | None = None) -> bool:
        """The chi-square gate on a bearing of a landmark in the graph (``nis_gate``, the same
        probability as the EKF's): its residual against the last LM pass's answer carried on with
        the odometry, over the variance of that prediction (the chain pose's covariance grown
        by the odometry since the pass, the landmark's marginal at the pass, ignoring their
        correlation) plus the bearing's own. A bearing far outside is a misread: in MRCLAM
        dataset 6 robot 3 reads landmark 11's barcode as 20's four times at 255 s (172 deg from
        where 20 is), robot 5 likewise at 582 s and 682-684 s; taken in, the squared error of
        those four outweighs turning the whole trajectory by 50 deg, and LM does (measured)."""
        if not math.isfinite(self.gate):
            return True
        sigma = self.data.sigma_bearing if sigma is None else sigma
        point, marginal = self._point(lm)
        pose = _pose(self.chain)
        if self._holds(lm):
            # first without the landmark's marginal (the narrowest test): a bearing it passes passes
            # with any; only one it fails needs the marginal, a Bayes-tree walk (reading it for every
            # bearing took 0.7 of iSAM2's 5 s on a 14,000-pose drive)
            r2, s = _bearing_test(pose, self.chain_cov, point, None, bearing, sigma)
            if r2 <= self.threshold(s) * s:
                return True
        r2, s = _bearing_test(pose, self.chain_cov, point, marginal(), bearing, sigma)
        return r2 <= self.threshold(s) * s

    def _marginals(self, result: gtsam.Values, e: int) -> None:
        """The newest pose's and the landmarks' marginals at an LM pass's answer (the gate's
        start); kept as they were if GTSAM cannot compute them."""
        if not math.isfinite(self.gate):
            return
        try:
            marginals = gtsam.Marginals(self.everything, result)
            heading = np.array([result.atPose2(X(e)).theta()])
            self.chain_cov = to_world(marginals.marginalCovariance(X(e))[None], heading)[0]
            for lm in self.points:
                self.point_cov[lm] = marginals.marginalCovariance(L(lm))
        except RuntimeError:
            pass

    def _update(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> bool:
        """``isam.update`` and the newest pose's estimate; False if GTSAM throws (an
        indeterminate system; the solver is then rebuilt by an LM pass)."""
        try:
            self.isam.update(graph, values)
            # the back-substitution (where an indeterminate system shows too) runs here
            self.current = self.isam.calculateEstimatePose2(X(self.done + 1))
            return True
        except RuntimeError:
            return False

    def _pass(self, e: int) -> bool:
        """LM over every factor so far from ``self.start``; the solver rebuilt at its answer.
        False if GTSAM throws."""
        try:
            result = gtsam.LevenbergMarquardtOptimizer(self.everything, self.start, _lm_params(50)).optimize()
            if self.isam is not None:
                isam = gtsam.ISAM2(self.params)
                isam.update(self.everything, result)
                current = isam.calculateEstimatePose2(X(e))
        except RuntimeError:
            return False
        self.passes += 1
        self.start = result
        self.chain = result.atPose2(X(e))
        self._marginals(result, e)
        for k in range(e + 1):
            self.known[k] = _pose(result.atPose2(X(k)))
        for lm in self.points:
            self.points[lm] = result.atPoint2(L(lm))
        self.current = self.chain
        if self.isam is not None:
            self.isam, self.current = isam, current
        return True

    FINAL_SOLVES = 3
    """Full relinearisations and solves of iSAM2 at the end of the log (:meth:`finish`)."""

    def finish(self) -> None:
        """At the end of the log: iSAM2 relinearised at every variable and solved in full,
        ``FINAL_SOLVES`` times, as an iSAM2 user closes a run (``ISAM2UpdateParams`` with
        ``force_relinearize`` and ``forceFullSolve``). Why: without LM passes, iSAM2's answer at the
        end carries the lag of its thresholds (a variable relinearised only past 0.1, a
        back-substitution stopped under 0.01): MRCLAM 6's stiff odometry then read 2.6-8.7 times
        its sigma in the diagnosis where the batch's read 0.8-1.2; finished, iSAM2's answer is the
        batch's to the figures' last digit (robots 1 and 4: 0.05-0.09 s, measured). The causal
        estimates, read before, do not change."""
        if self.isam is None:
            return
        params = gtsam.ISAM2UpdateParams()
        params.force_relinearize = True
        params.forceFullSolve = True
        try:
            for _ in range(self.FINAL_SOLVES):
                self.isam.update(gtsam.NonlinearFactorGraph(), gtsam.Values(), params)
        except RuntimeError:  # GTSAM's indeterminate system: the answer stays as it was held
            pass

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """The whole trajectory ``(E, 3)`` and map ``(N, 2)`` (NaN: not in the graph) as the
        solver (or the last LM pass) has them now."""
        values = self.start if self.isam is None else self.isam.calculateBestEstimate()
        poses = np.array([_pose(values.atPose2(X(k))) for k in range(self.done + 1)])
        points = np.full((len(self.data.landmarks), 2), np.nan)
        for lm in self.points:
            points[lm] = values.atPoint2(L(lm))
        return poses, points


MAP_FULL = 10
"""Every how many map readings :func:`read_map` reads every landmark's marginal, not only the seen ones'."""


def read_map(held: list[int], previous: np.ndarray, seen: np.ndarray, full: bool,
             mean_of: Callable[[int], np.ndarray], cov_of: Callable[[int], np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray]:
    """One reading of a smoother's map ``(N, 2)``, ``(N, 2, 2)``: the mean of every landmark ``held``;
    the marginal of those ``seen`` since the last reading, of all where ``full``, and of any whose
    ``previous`` one is not finite; the others' carried from ``previous``; NaN for what is not held.
    ``seen`` is cleared. Why: landmark marginals cost more than an update (a Bayes-tree walk each);
    read for the whole map every second, they took 13 of iSAM2's 17 s on a 1,400 s log and 29 of the
    fixed-lag smoother's 30 s on a 7,000-pose drive (measured)."""
    mean = np.full((len(previous), 2), np.nan)
    cov = previous.copy()
    for lm in held:
        mean[lm] = mean_of(lm)
        if full or seen[lm] or not np.isfinite(cov[lm]).all():
            cov[lm] = cov_of(lm)
    cov[~np.isfinite(mean[:, 0])] = np.nan
    seen[:] = False
    return mean, cov


def isam2(data: OmniData, cfg: OmniConfig, kf: Keyframes | None = None, map_every: float = math.inf
          ) -> SlamEstimate:
    """iSAM2, one update per keyframe; the newest pose and its marginal at every keyframe
    (causal, held to the filtering bound), and its whole trajectory at the end (``smoothed``:
    iSAM2 is a smoother; this is the answer batch LM is compared with).

    The map is read every ``map_every`` seconds and at the end (:func:`read_map`: the marginals of
    the landmarks seen since the last reading, all of them every ``MAP_FULL``-th reading and the
    last); Monte Carlo runs read it once, at the end.
    """
    kf = kf or keyframes(data, cfg)
    inc = _Incremental(data, cfg, kf)
    n_lm, E = len(data.landmarks), len(kf.steps)
    poses = np.empty((E, 3))
    covs = np.empty((E, 3, 3))
    map_steps, map_mean, map_cov = [], [], []
    last_map = -math.inf
    seen = np.zeros(n_lm, bool)
    cov = np.full((n_lm, 2, 2), np.nan)
    for e in range(E):
        poses[e] = inc.step(e)
        covs[e] = inc.newest_cov if inc.newest_cov is not None else _marginal(inc.isam, X(e), 3)
        if e == E - 1:
            inc.finish()
        seen[kf.bearings[e][0]] = True
        if data.t[kf.steps[e]] - last_map >= map_every or e == E - 1:
            last_map = data.t[kf.steps[e]]
            if inc.isam is None:  # iSAM2 gave up: the LM passes' map
                mean_of = inc.estimate()[1].__getitem__
            else:
                mean_of = functools.partial(_point_of, inc.isam)
            mean, cov = read_map(list(inc.points), cov, seen, e == E - 1 or len(map_steps) % MAP_FULL == 0,
                                 mean_of, functools.partial(_landmark_marginal, inc.isam))
            map_steps.append(kf.steps[e])
            map_mean.append(mean)
            map_cov.append(cov)
    return SlamEstimate("isam2", kf.steps.copy(), poses, to_world(covs, poses[:, 2]), np.array(map_steps),
                        np.array(map_mean), np.array(map_cov), inc.first_seen, inc.init_step,
                        failures=inc.failures, lm_passes=inc.passes,
                        gated_bearings=gated_indices(data, kf, inc.rejected),
                        smoothed=inc.estimate()[0], residuals=_held_residuals(data, cfg, kf, inc))


def _held_residuals(data: OmniData, cfg: OmniConfig, kf: Keyframes, inc: _Incremental):
    """iSAM2's residuals at the answer it holds at the end (:mod:`.residuals`), over the graph of
    its landmarks and the bearings it kept; None where it holds none."""
    if inc.isam is None:
        return None
    values = inc.isam.calculateBestEstimate()
    graph = _batch_graph(data, kf, inc.marks, inc.rejected)
    try:
        return residuals.of_graph(graph, values, kf, inc.marks.inserted, inc.rejected, cfg.nis_gate or None)
    except RuntimeError:  # a variable the graph holds that the answer does not
        return None


def _point_of(isam: gtsam.ISAM2, lm: int) -> np.ndarray:
    return isam.calculateEstimatePoint2(L(lm))


def _landmark_marginal(isam: gtsam.ISAM2 | None, lm: int) -> np.ndarray:
    return _marginal(isam, L(lm), 2)


def _marginal(isam: gtsam.ISAM2 | None, key: int, dim: int) -> np.ndarray:
    """A variable's marginal covariance; NaN where iSAM2 cannot give it (or has given up)."""
    if isam is None:
        return np.full((dim, dim), np.nan)
    try:
        return isam.marginalCovariance(key)
    except RuntimeError:
        return np.full((dim, dim), np.nan)


def batch(data: OmniData, cfg: OmniConfig, kf: Keyframes | None = None,
          starts: list[Start | Callable[[], Start]] | None = None) -> SlamEstimate:
    """Levenberg-Marquardt over the whole run; marginals for every pose.

    It starts from ``starts`` (default: those ``cfg`` names, :func:`named_starts`) in the order
    given, solving the next only while the last fit fails its chi-square test
    (:func:`_best_start`), and keeps the solution of the lowest :func:`robust_cost` on the data
    (never the truth); ``start`` / ``start_costs`` in the answer say which won and what each one
    solved cost. The
    starts: dead reckoning with the landmarks triangulated from it (``odometry``); the graph
    grown keyframe by keyframe with an LM pass every ``lm_every`` seconds and at every new
    landmark (``grown``: :class:`_Incremental` without iSAM2); another estimator's answer on the
    same data (:func:`start_from`: iSAM2's whole trajectory as it holds it at the end, the
    EKF's). Dead reckoning is enough in the paper's simulation; on MRCLAM it drifts tens of
    degrees and LM stops in a wrong minimum (2.8 m RMSE on robot 1). The grown graph can fall
    into a wrong basin too (on a real MRCLAM log it ended 3 m off with 2,560 bearings gated out
    while iSAM2's own smoothed trajectory was at 0.24 m): only the cost on the data tells them
    apart without truth, so the batch tries more than one.

    The start's gate judged each bearing against a prediction; the batch then re-gates every
    bearing against its own smoothed answer and solves again, until the verdict stands (at most
    ``REGATE_ROUNDS`` times): a good bearing left out while the prediction was off comes back.
    On MRCLAM 6 the left-out bearings go from 52-113 to 0-5 on robots 3-5 (robot 3's four
    misreads and robot 5's stay out) and robot 4's RMSE from 0.48 to 0.43 m.
    """
    kf = kf or keyframes(data, cfg)
    E = len(kf.steps)
    starts = list(starts or named_starts(data, cfg, kf))
    solved, costs = _best_start(data, cfg, kf, starts)
    won = min(solved, key=lambda i: (costs[i], i))  # the first listed on a tie
    result, marks, rejected, first_seen, init_step = solved[won]
    graph = _batch_graph(data, kf, marks, rejected)
    covs, lm_cov = _batch_marginals(graph, result, E, marks.inserted)
    for _ in range(REGATE_ROUNDS if cfg.nis_gate > 0.0 or outlier_rate(cfg) > 0.0 else 0):
        again = _regate(data, cfg, kf, result, covs, lm_cov, marks.inserted)
        if again == rejected:
            break
        rejected = again
        result = _drop_unseen(kf, marks, rejected, result)
        graph = _batch_graph(data, kf, marks, rejected)
        result = gtsam.LevenbergMarquardtOptimizer(graph, result, _lm_params(100)).optimize()
        covs, lm_cov = _batch_marginals(graph, result, E, marks.inserted)
    poses = np.array([_pose(result.atPose2(X(e))) for e in range(E)])
    mean = np.full((len(data.landmarks), 2), np.nan)
    for lm in np.flatnonzero(marks.inserted):
        mean[lm] = result.atPoint2(L(int(lm)))
    return SlamEstimate("gtsam-batch", kf.steps.copy(), poses, to_world(covs, poses[:, 2]),
                        np.array([kf.steps[-1]]), mean[None], lm_cov[None], first_seen, init_step,
                        gated_bearings=gated_indices(data, kf, rejected), start=starts[won].name,
                        start_costs={starts[i].name: float(c) for i, c in costs.items()},
                        fit=fit(graph, result, E, int(marks.inserted.sum())),
                        residuals=residuals.of_graph(graph, result, kf, marks.inserted, rejected, cfg.nis_gate or None))


def fit(graph: gtsam.NonlinearFactorGraph, result: gtsam.Values, poses: int, landmarks: int) -> tuple[float, int]:
    """The least-squares fit's chi-square: twice the graph's error at its answer (every factor's
    squared whitened residual: the prior, the odometry, the bearings kept) and its degrees of
    freedom, the residuals less the unknowns (``3 poses + 2 landmarks``). With the noise the model
    says and the right minimum it is chi-square with those degrees of freedom (the residual sum of
    squares of a linear(ised) least-squares fit: Bar-Shalom, Li, Kirubarajan, sec. 3.4); a wrong
    basin or a wrong noise model puts it far above. Readings: the bearings a gate left out are not
    counted (their test is the gate's), which biases it low by a little where the gate cut the
    tail of good ones (0.99: 1 % of them)."""
    residuals = sum(graph.at(i).dim() for i in range(graph.size()))
    return 2.0 * float(graph.error(result)), int(residuals - 3 * poses - 2 * landmarks)


def _drop_unseen(kf: Keyframes, marks: _Landmarks, rejected: set[tuple[int, int]], result: gtsam.Values
                 ) -> gtsam.Values:
    """Take out of the map every landmark the gate left fewer than two bearings of (one ray does
    not fix a point: the system would be indeterminate)."""
    kept = np.zeros(len(marks.inserted), int)
    for e, (lms, _) in enumerate(kf.bearings):
        for lm in lms.tolist():
            kept[lm] += (e, lm) not in rejected
    out = gtsam.Values(result)
    for lm in np.flatnonzero(marks.inserted & (kept < 2)):
        marks.inserted[lm] = False
        out.erase(L(int(lm)))
    return out


@dataclass
class Start:
    """Where the batch starts: ``poses (E, 3)`` at the keyframes, ``landmarks (N, 2)`` (NaN:
    triangulate from the poses), and the bearings ``(keyframe, landmark)`` that whatever made
    the start left out (its gate; the batch leaves them out too until it re-gates)."""

    name: str
    poses: np.ndarray
    landmarks: np.ndarray
    rejected: set[tuple[int, int]]


GROWN_EVERY = 20.0
"""s: the grown start's LM period where ``lm_every`` is 0 (iSAM2 without passes)."""


def own_start(data: OmniData, cfg: OmniConfig, kf: Keyframes, name: str | None = None) -> Start:
    """The batch's own start ``name`` (default: ``grown`` with ``lm_every > 0``, else
    ``odometry``): dead reckoning, or the graph grown with its LM passes."""
    name = name or ("grown" if cfg.lm_every > 0.0 else "odometry")
    if name == "grown":
        grown = cfg if cfg.lm_every > 0.0 else dataclasses.replace(cfg, lm_every=GROWN_EVERY)
        inc = _Incremental(data, grown, kf, solver=False)
        for e in range(len(kf.steps)):
            inc.step(e)
        return Start("grown", *inc.estimate(), inc.rejected)
    if name != "odometry":
        raise ValueError(f"the batch's own starts are odometry and grown, not {name!r}")
    return Start("odometry", kf.dead_reckoning, np.full((len(data.landmarks), 2), np.nan), set())


def named_starts(data: OmniData, cfg: OmniConfig, kf: Keyframes,
                 made: dict[str, Callable[[], SlamEstimate]] | None = None) -> list[Callable[[], Start]]:
    """The starts ``--batch-starts`` names, in order, each as a function that makes it (the batch
    makes only those it solves): the batch's own (:func:`own_start`) and other estimators' answers
    (:func:`start_from`), those made by ``made[name]()`` where given (a run's shared estimate),
    else run here."""
    def run(name: str) -> SlamEstimate:
        if made and name in made:
            return made[name]()
        if name == "isam2":
            return isam2(data, cfg, kf)
        from workbench.experiments.omni import ekf

        return ekf.run(data, cfg, "clone", "ekf", False)

    def make(name: str) -> Callable[[], Start]:
        if name in ("isam2", "ekf"):
            return lambda: start_from(name, run(name), data, kf)
        return lambda: own_start(data, cfg, kf, name)

    return [make(n) for n in cfg.starts]


def start_from(name: str, est: SlamEstimate, data: OmniData, kf: Keyframes) -> Start:
    """A start from another estimator's answer on the same data: its whole trajectory as it holds
    it at the end where it keeps one (``smoothed``), else its poses, at the keyframes; its final
    map; the bearings its gate left out."""
    where = np.clip(np.searchsorted(est.steps, kf.steps), 0, len(est.steps) - 1)
    poses = (est.smoothed if est.smoothed is not None else est.pose)[where]
    if not np.array_equal(est.steps[where], kf.steps) or not np.isfinite(poses).all():
        raise ValueError(f"the batch's start {name!r} needs a finite pose at every keyframe")
    index = {int(s): e for e, s in enumerate(kf.steps)}
    rejected = set()
    for i in (est.gated_bearings if est.gated_bearings is not None else ()):
        if i >= 0 and int(data.meas_step[i]) in index:
            rejected.add((index[int(data.meas_step[i])], int(data.meas_lm[i])))
    return Start(name, poses.copy(), est.final_map.copy(), rejected)


def _best_start(data: OmniData, cfg: OmniConfig, kf: Keyframes, starts: list[Start | Callable[[], Start]]
                ) -> tuple[dict[int, tuple], dict[int, float]]:
    """LM from the starts in the order given (one given as a function is made when it is reached;
    ``starts`` then holds it) until one ends with a fit its chi-square does not
    reject (:func:`plausible`); the rest are not solved. Returns the solved ones and their
    :func:`robust_cost`, by index.

    Why: solving from every start cost a full LM solve of the whole run each (two of a long log's
    three solves, measured), though a fit that passes its test needs no second opinion. Where it
    fails (a wrong basin: a mirrored trajectory's is many times its degrees of freedom; or a wrong
    noise model), the next start is solved too and the lower cost on the data kept, as before.
    """
    solved: dict[int, tuple] = {}
    costs: dict[int, float] = {}
    for i, start in enumerate(starts):
        if callable(start):  # made only when it is needed
            start = starts[i] = start()
        values, marks, rejected, first_seen, init_step = _prepare(data, cfg, kf, start)
        graph = _batch_graph(data, kf, marks, rejected)
        result = gtsam.LevenbergMarquardtOptimizer(graph, values, _lm_params(100)).optimize()
        solved[i] = (result, marks, rejected, first_seen, init_step)
        costs[i] = robust_cost(data, cfg, kf, result, marks.inserted)
        if plausible(*fit(graph, result, len(kf.steps), int(marks.inserted.sum()))):
            break
    return solved, costs


FIT_TEST = 0.999
"""The probability at which :func:`plausible` rejects a least-squares fit."""


def plausible(chi2: float, dof: int) -> bool:
    """Whether a fit's chi-square (:func:`fit`) is under its ``FIT_TEST`` quantile (a fit far under
    it is a noise assumed too wide, not a wrong basin: accepted)."""
    return dof > 0 and chi2 <= chi2_quantile(FIT_TEST, dof)


def _prepare(data: OmniData, cfg: OmniConfig, kf: Keyframes, start: Start):
    """The batch's values at ``start`` (its poses, the landmarks it places or triangulated from
    them): ``(values, landmarks, rejected, first_seen, init_step)``.

    A landmark a start with a map left out (iSAM2's, the EKF's, the grown graph's) enters only by
    the consensus of its rays (:func:`consensus`, where a gate is on: each ray within the gate of
    twice the bearing's variance, for the bearing's noise and as much for the start's poses),
    its rays that disagree left out: the start did not map it because its rays disagree. Why: on a
    drive with 10 % of the ids misread, the rays of such landmarks, triangulated as they came,
    brought hundreds of misreads in and took the batch from iSAM2's 1.1 m to 3.7 m (its fit 1.3e5
    times its degrees of freedom, measured). Dead reckoning's start maps nothing and vouches for
    nothing: its landmarks enter as before (its poses drift too far for a tight consensus)."""
    n_lm, E = len(data.landmarks), len(kf.steps)
    mapped = np.isfinite(start.landmarks).all(axis=1)
    threshold = gate_of(cfg)
    gated = cfg.nis_gate > 0.0 or outlier_rate(cfg) > 0.0
    marks = _Landmarks(n_lm, data.sigma_bearing, math.radians(cfg.graph_parallax_deg), cfg.huber)
    values = gtsam.Values()
    for e in range(E):
        values.insert(X(e), gtsam.Pose2(*start.poses[e]))
    first_seen = np.full(n_lm, -1)
    init_step = np.full(n_lm, -1)
    for e in range(E):  # which landmarks enter, where they start (their factors: _batch_graph)
        lms, bearings = kf.bearings[e]
        for lm, b, sigma in zip(lms, bearings, kf.sigma(e), strict=True):
            lm, b = int(lm), float(b)
            if first_seen[lm] < 0:
                first_seen[lm] = kf.steps[e]
            if (e, lm) in start.rejected:
                continue
            preset = start.landmarks[lm] if mapped[lm] else None
            tolerance = math.inf
            if preset is None and gated and mapped.any():
                s2 = 2.0 * float(sigma) ** 2
                tolerance = math.sqrt(max(float(threshold(s2)), 0.0) * s2)
            _, point = marks.observe(e, lm, b, lambda k: start.poses[k], preset, tolerance, sigma=float(sigma))
            if point is None:
                continue
            values.insert(L(lm), point)
            init_step[lm] = kf.steps[e]
    return values, marks, set(start.rejected) | set(marks.outliers), first_seen, init_step


def outlier_rate(cfg: OmniConfig) -> float:
    """The bearings' outlier share the estimators assume (``assume_outlier_rate``; 0: none)."""
    return float(cfg.assume_outlier_rate or 0.0)


def gate_of(cfg: OmniConfig) -> Callable[[np.ndarray | float], np.ndarray | float]:
    """The normalised squared bearing residual beyond which the graphs leave a bearing of
    variance ``s`` out, as a function of ``s``: the outlier model's even odds
    (:func:`workbench.estimation.outliers.even_odds`) where the config assumes one, else the
    chi-square gate ``nis_gate`` (inf where it is off), made once for a pass over the bearings."""
    rate = outlier_rate(cfg)
    if rate > 0.0:
        return lambda s: outliers.even_odds(s, rate)
    chi2 = chi2_quantile(cfg.nis_gate, 1) if cfg.nis_gate > 0.0 else math.inf
    return lambda s: chi2


def gate_nis(cfg: OmniConfig, s: np.ndarray | float) -> np.ndarray | float:
    """:func:`gate_of`'s threshold at ``s``."""
    return gate_of(cfg)(s)


def robust_cost(data: OmniData, cfg: OmniConfig, kf: Keyframes, result: gtsam.Values, inserted: np.ndarray
                ) -> float:
    """The data's cost under a solution, the same for every start whatever it left out: the prior's
    and the odometry factors' errors (half their squared Mahalanobis norms) plus, for every bearing
    at a keyframe, half its squared normalised residual truncated at the gate's chi-square
    quantile (``nis_gate``, 0.99 where the gate is off; with an outlier model its even odds,
    :func:`gate_of`, where the truncated cost is the mixture's likelihood's), a bearing of a landmark not in the map
    counting as one at the gate. Truncated least squares (Yang, Antonante, Tzoumas, Carlone,
    "Graduated non-convexity for robust spatial perception", RA-L 2020, eq. 3): a solution cannot
    lower its cost by leaving bearings out, each one out costs as much as the worst one kept, so
    a wrong basin that gates thousands of bearings out costs more than the right one."""
    cost = _odometry_graph(data, kf).error(result)
    e = np.concatenate([np.full(len(lms), k) for k, (lms, _) in enumerate(kf.bearings)]).astype(int)
    lm = np.concatenate([lms for lms, _ in kf.bearings]).astype(int)
    b = np.concatenate([bs for _, bs in kf.bearings])
    sigma = np.concatenate(kf.sigmas) if kf.sigmas is not None else np.full(len(b), data.sigma_bearing)
    gate = (gate_of(cfg)(sigma ** 2) if outlier_rate(cfg) > 0.0
            else np.full(len(b), chi2_quantile(cfg.nis_gate if cfg.nis_gate > 0.0 else 0.99, 1)))
    mapped = inserted[lm]
    r2 = gate.copy()  # a bearing of a landmark not in the map counts at the gate
    if mapped.any():
        pose = np.array([_pose(result.atPose2(X(k))) for k in range(len(kf.steps))])[e[mapped]]
        points = {k: result.atPoint2(L(k)) for k in np.unique(lm[mapped]).tolist()}
        d = np.array([points[k] for k in lm[mapped].tolist()]) - pose[:, :2]
        r = wrap(b[mapped] - (np.arctan2(d[:, 1], d[:, 0]) - pose[:, 2]))
        r2[mapped] = np.minimum(r * r / sigma[mapped] ** 2, gate[mapped])
    return float(cost + 0.5 * r2.sum())


REGATE_ROUNDS = 3
"""How many times the batch re-gates every bearing against its own smoothed answer."""


def _batch_graph(data: OmniData, kf: Keyframes, marks: _Landmarks, rejected: set[tuple[int, int]]
                 ) -> gtsam.NonlinearFactorGraph:
    """The batch's factors: the start's prior, the odometry between keyframes, and every bearing
    of a landmark in the graph (``marks.inserted``) but those ``(keyframe, landmark)`` in
    ``rejected`` (what :meth:`_Landmarks.observe` hands out over the run, held rays included)."""
    graph = _odometry_graph(data, kf)
    for e, (lms, bearings) in enumerate(kf.bearings):
        for lm, b, sigma in zip(lms.tolist(), bearings.tolist(), kf.sigma(e).tolist(), strict=True):
            if marks.inserted[lm] and (e, lm) not in rejected:
                if sigma != marks.default:
                    marks.own[(e, lm)] = sigma
                graph.add(marks.factor(e, lm, b))
    return graph


def _odometry_graph(data: OmniData, kf: Keyframes) -> gtsam.NonlinearFactorGraph:
    """The start's prior and the odometry between keyframes: every graph's first factors."""
    graph = gtsam.NonlinearFactorGraph()
    graph.add(_prior(data))
    for e, (odo, cov) in enumerate(kf.between, start=1):
        graph.add(gtsam.BetweenFactorPose2(X(e - 1), X(e), odo, _noise(cov)))
    return graph


def _bearing_test(pose: np.ndarray, pose_cov: np.ndarray, point: np.ndarray, point_cov: np.ndarray | None,
                  bearing: float, sigma: float) -> tuple[float, float]:
    """A bearing's squared residual from ``pose`` to ``point`` and its variance there: the pose's
    (world frame) and the point's covariance through the bearing's Jacobian (their correlation
    ignored; one not given or not finite left out) plus the bearing's own ``sigma^2``. A point on
    the pose has nothing to test: ``(0, 1)``."""
    d = np.asarray(point, float) - pose[:2]
    q = float(d @ d)
    if q < 1e-12:
        return 0.0, 1.0
    r = float(wrap(bearing - (math.atan2(d[1], d[0]) - pose[2])))
    s = sigma ** 2
    for h, cov in ((np.array([d[1] / q, -d[0] / q, -1.0]), pose_cov), (np.array([-d[1], d[0]]) / q, point_cov)):
        if cov is not None and np.isfinite(cov).all():
            s += float(h @ cov @ h)
    return r * r, s


def _batch_marginals(graph: gtsam.NonlinearFactorGraph, result: gtsam.Values, E: int, inserted: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Every keyframe pose's ``(E, 3, 3)`` (body frame) and landmark's ``(N, 2, 2)`` marginal; NaN
    where GTSAM cannot compute them."""
    lm_cov = np.full((len(inserted), 2, 2), np.nan)
    try:
        marginals = gtsam.Marginals(graph, result)
        covs = np.array([marginals.marginalCovariance(X(e)) for e in range(E)])
        for lm in np.flatnonzero(inserted):
            lm_cov[lm] = marginals.marginalCovariance(L(int(lm)))
    except RuntimeError:
        covs = np.full((E, 3, 3), np.nan)
    return covs, lm_cov


def _regate(data: OmniData, cfg: OmniConfig, kf: Keyframes, result: gtsam.Values, covs: np.ndarray,
            lm_cov: np.ndarray, inserted: np.ndarray) -> set[tuple[int, int]]:
    """The bearings ``(keyframe, landmark)`` the chi-square gate (``nis_gate``) leaves out against
    the smoothed answer: each one's residual at ``result`` over its variance there (the pose's and
    the landmark's marginals, their correlation ignored, plus the bearing's own). The grown
    graph gated causally, against a prediction; a bearing it left out while its prediction was
    off comes back here, and one it took in that the whole run disagrees with goes."""
    out = set()
    threshold = gate_of(cfg)
    for e in range(len(kf.steps)):
        lms, bearings = kf.bearings[e]
        if len(lms) == 0:
            continue
        pose = _pose(result.atPose2(X(e)))
        pose_cov = to_world(covs[e][None], np.array([pose[2]]))[0]
        for lm, b, sigma in zip(lms.tolist(), bearings.tolist(), kf.sigma(e).tolist(), strict=True):
            if not inserted[lm]:
                continue
            r2, s = _bearing_test(pose, pose_cov, result.atPoint2(L(lm)), lm_cov[lm], b, sigma)
            if r2 > threshold(s) * s:
                out.add((e, lm))
    return out


def gated_indices(data: OmniData, kf: Keyframes, rejected: set[tuple[int, int]]) -> np.ndarray:
    """The dataset's indices of the bearings ``(keyframe, landmark)`` a gate left out."""
    if not rejected:
        return np.zeros(0, int)
    keys = {(int(kf.steps[e]), lm) for e, lm in rejected}
    pairs = zip(data.meas_step.tolist(), data.meas_lm.tolist(), strict=True)
    return np.array([i for i, key in enumerate(pairs) if key in keys], int)
