"""``isam2``: iSAM2 (QR factorisation, relinearisation threshold ``relin_threshold``) updated at
every keyframe; its newest pose at that time is what a causal estimator knows, so it is
comparable to the filter's. A damped Levenberg-Marquardt pass over the graph so far runs only
where an update runs away; with ``lm_every > 0`` also every ``lm_every`` seconds and whenever a
landmark enters (:class:`_Incremental` says why that is no longer the default), the passes' cost
held to :data:`PASS_BUDGET`. The estimator that reads it is :func:`.isam2_estimator.isam2`."""

from __future__ import annotations

import math
from collections.abc import Callable

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms.graph import relocation
from workbench.experiments.omni.algorithms.graph.gating import _bearing_test, gate_of, outlier_rate
from workbench.experiments.omni.algorithms.graph.keyframes import (
    Keyframes,
    _lm_params,
    _noise,
    _pose,
    _prior,
    compose_cov,
    poses_of,
    to_world,
)
from workbench.experiments.omni.algorithms.graph.landmarks import _Landmarks
from workbench.experiments.omni.algorithms.graph.marginals import _marginal, pass_marginals
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData

JUMP_POSITION = 2.0


JUMP_HEADING = math.radians(10.0)

SETTLED = 0.05
"""A jump's next Gauss-Newton step within this share of the jump thresholds (0.1 m, 0.5 deg):
the jump was a correction, not a run-away (:meth:`_Incremental._settles`)."""

PASS_BUDGET = 20.0
"""The whole-graph LM passes at run-aways may solve, summed, at most this many graphs of the log's
length so far (their keyframes, each pass's count; a pass that re-gates solves twice,
:class:`.pruned._Pruned`): the passes' cost then grows as the log does, not as its square. A run
whose iSAM2 runs away again as soon as a pass rebuilds it spends the budget, and iSAM2 is given up
(as where a pass throws). On MRCLAM 6 at the scenario's noise the passes spend 0.4-1.6 of it (3-8
passes, measured); told a bearing sigma of 0.58 deg, robot 1's would have spent 84 (205 passes).
Why 20, not 10: with 1-2 % of MRCLAM's barcodes misread, each run-away pass leaves misreads out and
iSAM2 recovers, but 6 of 20 logs spent 10 before it had (``benchmarks/mrclam_misreads.py``'s logs,
iSAM2's smoothed answer within 0.5 m in 11 of 20 at 10, 16 at 20 and at 30; its cost up to 13 s)."""


def _jumped(predicted: gtsam.Pose2, estimate: gtsam.Pose2) -> bool:
    """Whether an update moved the newest pose implausibly far from its odometry prediction."""
    d = predicted.between(estimate)
    return math.hypot(d.x(), d.y()) > JUMP_POSITION or abs(d.theta()) > JUMP_HEADING


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
    away (:func:`_jumped`, and a second Gauss-Newton step does not settle it: :meth:`_settles`)
    or throws. ``ISAM2DoglegParams`` (a trust region inside iSAM2) was
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
        self.marks = _Landmarks.of(data, cfg)
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
        self.pass_work = 0        # the keyframes of every run-away pass's graph, summed (PASS_BUDGET)
        self.gave_up: int | None = None   # the keyframe at which iSAM2 was given up, if it was
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
        # each landmark's bearings, how many left out since it was last looked at, those placed again (relocation)
        self.rays: dict[int, list[tuple[int, float]]] = {}
        self.left_since: dict[int, int] = {}
        self.look_after: dict[int, int] = {}
        self.look_work = 0
        self.relocated: list[tuple[int, int]] = []

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
            self.rays.setdefault(lm, []).append((e, b))
            if marks.inserted[lm] and not self._consistent(lm, b, sigma):
                self.rejected.add((e, lm))
                self.left_since[lm] = self.left_since.get(lm, 0) + 1
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
        if not threw and self.isam is not None and _jumped(predicted, self.current) and not self._settles():
            # iSAM2 takes one undamped Gauss-Newton step per update; a newest pose thrown
            # metres or tens of degrees from its prediction that a second step moves on is such a
            # step running away: a damped LM pass over the graph so far brings it back
            threw = True
            self.runaways += 1
        kept = self.everything.size()
        self.everything.push_back(graph)
        self.start.insert(values)
        self.start.update(X(e), self.chain)
        self.done = e
        if self.follow and not threw and self.isam is not None and self.pass_work + e + 1 <= PASS_BUDGET * (e + 1):
            threw = any([relocation.relocate(self, e, lm) for lm in set(lms.tolist()) if relocation.due(self, e, lm)])
        t = self.data.t[kf.steps[e]]
        periodic = cfg.lm_every > 0.0 and (entered or t - self.last_pass >= cfg.lm_every)
        if threw and not periodic and self.isam is not None and self.pass_work + e + 1 > PASS_BUDGET * (e + 1):
            # the run-away passes have solved PASS_BUDGET graphs of the log's length so far: iSAM2
            # runs away again as soon as it is rebuilt, and more passes would make the cost grow as
            # the log's square (MRCLAM 6 robot 1 told a bearing sigma of 0.58 deg: 205 passes, 11 s
            # for a 1 s run). It gives up: the answer is the last pass's carried on with the odometry.
            self.failures += 1
            self.gave_up = e
            self.isam = None
        elif threw or periodic:
            self.last_pass = t
            self.pass_work += 0 if periodic else e + 1
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
                    self.isam, self.gave_up = None, e
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
    (0.6 ms for 2,900 variables; 0.05 s over a 14,000-pose drive)."""

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

    def _settles(self) -> bool:
        """After an update that threw the newest pose past :func:`_jumped`'s thresholds: whether
        that was a correction (a landmark seen again after a blind stretch turns the heading back
        by 10-30 deg) rather than a step running away. One more Gauss-Newton iteration of iSAM2,
        every variable past the relinearisation threshold relinearised (``force_relinearize``,
        1-10 ms on MRCLAM where a whole-graph LM pass takes 80), and the newest pose must stay
        within :data:`SETTLED` of the thresholds of where the jump put it: Gauss-Newton converges
        fast near the optimum, and a run-away's next step is as large as its first. On MRCLAM 6
        robots 1-5 (36 jumps, an LM pass beside each) LM lands within 0.07 m and 0.7 deg of the 12
        that settled, and up to 1.2 m and 59 deg from the 24 that did not (docs/long-logs.md)."""
        jumped = self.current
        params = gtsam.ISAM2UpdateParams()
        params.force_relinearize = True
        try:
            self.isam.update(gtsam.NonlinearFactorGraph(), gtsam.Values(), params)
            self.current = self.isam.calculateEstimatePose2(X(self.done + 1))
        except RuntimeError:
            return False
        d = jumped.between(self.current)
        return math.hypot(d.x(), d.y()) <= SETTLED * JUMP_POSITION and abs(d.theta()) <= SETTLED * JUMP_HEADING

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
        for k in range(e + 1):
            self.known[k] = _pose(result.atPose2(X(k)))
        for lm in self.points:
            self.points[lm] = result.atPoint2(L(lm))
        self.current = self.chain
        if self.isam is not None:
            self.isam, self.current = isam, current
        following = self.follow and self.isam is not None and math.isfinite(self.gate)
        cov = _marginal(self.isam, X(e), 3) if following else None
        if cov is not None and np.isfinite(cov).all():
            # iSAM2, rebuilt at LM's answer, holds the marginals ``Marginals`` would give there (its
            # Bayes tree is linearised at that answer): the newest pose's read from it now, the
            # landmarks' again when the gate next asks (a whole-graph ``Marginals`` at every pass
            # cost 0.02 s of 1.5 s on the 7,000-pose drive)
            self.newest_cov = cov
            self.chain_cov = to_world(cov[None], np.array([self.chain.theta()]))[0]
            self.point_read.clear()
        else:
            pass_marginals(self, result, e)
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
        except RuntimeError:
            # GTSAM's indeterminate system, thrown mid-update, leaves the Bayes tree half
            # eliminated: every later reading throws too (MRCLAM 6 robot 1 told a bearing sigma of
            # 0.58 deg, landmark 13). One damped LM pass over the graph rebuilds the solver; where
            # that throws as well, the answer is the last pass's carried on with the odometry.
            if not self._pass(self.done):
                self.isam, self.gave_up = None, self.done

    def values(self) -> gtsam.Values:
        """Every variable as the solver has it now; where iSAM2 gave up (or was never built), the
        last LM pass's answer carried on with the odometry (what it returns)."""
        return self.start if self.isam is None else self.isam.calculateBestEstimate()

    def estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """The whole trajectory ``(E, 3)`` and map ``(N, 2)`` (NaN: not in the graph) as
        :meth:`values` has them."""
        values = self.values()
        poses = poses_of(values, self.done + 1)
        points = np.full((len(self.data.landmarks), 2), np.nan)
        for lm in self.points:
            points[lm] = values.atPoint2(L(lm))
        return poses, points
