"""Landmarks entering the graph: a landmark enters only once two of its rays meet with
``graph_parallax`` or more (held-back factors are added then; a landmark seen from one place
only leaves the linear system indeterminate), placed by the consensus of its rays and refined by
Gauss-Newton; each bearing a ``BearingFactor2D``, Huber-robust beyond ``huber`` sigmas where
that is set."""

from __future__ import annotations

import math
from collections.abc import Callable

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.estimation.angles import wrap
from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms.graph.keyframes import Keyframes, _odometry_graph
from workbench.experiments.omni.algorithms.triangulation import rays
from workbench.experiments.omni.scenario import OmniData

AGREEING = 3
"""The rays that must agree on a landmark's place (:func:`consensus`)."""


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


def sigma_of(model: gtsam.noiseModel.Base) -> float:
    """A bearing factor's sigma, its Gaussian's where the model is robust (``Robust.sigmas`` throws)."""
    return float((model.noise() if isinstance(model, gtsam.noiseModel.Robust) else model).sigmas()[0])


class _Landmarks:
    """Held-back bearings per landmark until two rays give a good intersection."""

    def __init__(self, n: int, sigma: float, min_parallax: float, huber: float = 0.0,
                 baseline: Callable[[int, int], float] | None = None, fov: float = 2.0 * math.pi):
        self.baseline = baseline  # (keyframe, keyframe) -> the least distance between them that is not noise
        self.fov = fov  # rad: the field of view (:meth:`trusted`)
        self.obs: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        self.inserted = np.zeros(n, bool)
        self.outliers: list[tuple[int, int]] = []
        self.noise = bearing_noise(sigma, huber)
        self.min_parallax = min_parallax
        self.default, self.huber = sigma, huber
        self.own: dict[tuple[int, int], float] = {}  # (keyframe, landmark) -> its bearing's own sigma
        self.noises: dict[float, gtsam.noiseModel.Base] = {}

    @classmethod
    def of(cls, data: OmniData, cfg, huber: float | None = None) -> _Landmarks:
        """The graph estimators' bookkeeping for ``data`` as ``cfg`` sets it (the bearings' sigma, the
        parallax a landmark enters with, the Huber threshold, ``cfg.huber`` unless ``huber`` is given,
        the field of view)."""
        return cls(len(data.landmarks), data.sigma_bearing, math.radians(cfg.graph_parallax_deg),
                   cfg.huber if huber is None else huber, fov=data.fov)

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
            if not self.trusted(point, poses, inlier, tolerance):
                return [], None  # not yet (:meth:`trusted`)
            self.outliers.extend((k, lm) for (k, _), ok in zip(self.obs[lm], inlier, strict=True) if not ok)
            self.obs[lm] = [o for o, ok in zip(self.obs[lm], inlier, strict=True) if ok]
        else:
            point = preset if preset is not None else self.try_insert(lm, pose_of)
        if point is None:
            return [], None
        self.inserted[lm] = True
        return [self.factor(k, lm, bk) for k, bk in self.obs[lm]], point

    def trusted(self, point: np.ndarray, poses: np.ndarray, inlier: np.ndarray, tolerance: float) -> bool:
        """Whether a landmark may enter at the ``point`` its held rays' consensus gives (``inlier``:
        the rays that agree). Where the id shows misreads (some held rays disagree) or only
        :data:`AGREEING` rays are held (nothing could show one), it enters only where (i) every
        agreeing ray is checked by the others (:func:`controlled`) and (ii) the agreeing rays are
        more than chance: :func:`chance_agreement` under :data:`CHANCE`, with a ray pointing anywhere
        in the field of view passing within ``tolerance`` of a place with probability
        ``2 tolerance / fov`` (the batch's ghost rule, applied at entry; three rays of three agree by
        chance ``3 p``, so a landmark held on three waits for a fourth). Otherwise it waits for more
        rays: the next sightings decide.

        Why: an id whose held rays include misreads (another landmark's bearings) gets a place
        where one of them crosses its true rays or where three misreads cross. A synthetic log with
        10 % misread ids, seed 1: landmark 74 held three misread rays, then two true ones a keyframe
        apart; a misread from the side crossed those two 46 m from the landmark and fixed its range
        alone (leverage 1, residual 0); it entered there, iSAM2 turned 33 deg within ten keyframes
        following it and ended 34 m off (1.1 m with this test; seed 0's map 24.7 -> 0.56 m, ids
        never seen no longer mapped). Why not everywhere: on MRCLAM a landmark is often seen once
        from one place and many times from another, a ray its range rests on alone; holding every
        such entry back for a second view delayed robot 1's landmarks 11, 10 and 12 into a stretch
        where its pose was 1 m off, and its iSAM2 ended 7-170 m off in five of seven runs with a
        threshold moved by a tenth (relinearisation, parallax, gate), against 0.14 m in all seven
        with the test only where misreads show. Nor where the tolerance spans the field of view
        (``p = 1``: any ray agrees, a fourth as surely as a third, so waiting for it teaches
        nothing): after a blind stretch robot 1's gate reads 41 deg either side in a field of 66,
        and holding landmarks 11 and 10 for a fourth ray (0.7 and 1.9 s) sent its iSAM2 into a
        wrong basin it gave up in, 27.9 m off, told a speed sigma of 0.023 and a turn sigma of 1.72
        deg (what ``--tune-noise`` finds; at 2 of 9 noises about the scenario's; at none with them
        entering: 0.36-0.54 m)."""
        p = ray_chance(tolerance, self.fov)
        if inlier.all() and (len(inlier) > AGREEING or p >= 1.0):
            # (a tolerance the width of the field of view: any ray agrees, a fourth as surely as a
            # third, and waiting for it teaches nothing)
            return True
        return controlled(point, poses[inlier]) and chance_agreement(len(inlier), int(inlier.sum()), p) <= CHANCE

    def try_insert(self, lm: int, pose_of) -> np.ndarray | None:
        """The landmark's starting point, or None while the first sighting's and the newest
        one's rays do not meet in front of both with ``min_parallax``. The two rays' meeting
        point is refined by least squares over every held ray (:func:`refine`)."""
        first, newest = self.obs[lm][0], self.obs[lm][-1]
        a, b = pose_of(first[0]), pose_of(newest[0])
        if self.baseline is not None and math.hypot(b[0] - a[0], b[1] - a[1]) < self.baseline(first[0], newest[0]):
            return None   # the rays' parallax would be the odometry's noise (a robot turning on the spot)
        point = _parallax_ok(a, first[1], b, newest[1], self.min_parallax)
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
    if best is None or best[0] < AGREEING:
        return None
    point = best[2]
    agree = np.abs(_residuals(point, poses, bearings)) < tolerance
    point = refine(point, poses[agree], bearings[agree])
    agree = np.abs(_residuals(point, poses, bearings)) < tolerance
    return (point, agree) if agree.sum() >= AGREEING else None


CHANCE = 0.01
"""A landmark whose agreeing rays pointing anywhere would match this often is not taken."""


def ray_chance(tolerance: float, fov: float) -> float:
    """The chance that a ray pointing anywhere in a field of view ``fov`` (rad) passes within
    ``tolerance`` (rad) of a given place: the tolerance's share of the field of view."""
    return min(1.0, 2.0 * tolerance / min(float(fov), 2.0 * math.pi))


def chance_agreement(n: int, k: int, p: float) -> float:
    """How often ``k`` of ``n`` rays that point anywhere would agree on one place (a bound): each
    of the ``n (n - 1) / 2`` pairs meets somewhere, and ``k - 2`` of the other ``n - 2`` pass within
    the tolerance of it, each with probability ``p`` (the tolerance's share of the field of view)."""
    from scipy.stats import binom  # (here: scipy.stats takes a third of a second to import)

    if n < 2 or k < 2:
        return 1.0
    return float(min(1.0, n * (n - 1) / 2 * binom.sf(k - 3, n - 2, p)))


UNCONTROLLED = 0.9
"""A ray whose leverage in its landmark's place is over this (redundancy number ``1 - h_ii`` under
0.1) is not checked by the others: geodesy's uncontrolled observation (Förstner 1987, "Reliability
analysis of parameter estimation in linear models with applications to mensuration problems in
computer vision", CVGIP 40; Koch, *Parameter Estimation and Hypothesis Testing in Linear Models*)."""


def controlled(point: np.ndarray, poses: np.ndarray) -> bool:
    """Whether every ray that places a landmark at ``point`` from ``poses`` is checked by the others:
    its leverage ``J_i (J' J)^-1 J_i'`` at most :data:`UNCONTROLLED` (a place's two coordinates share
    2 among all rays; three rays spread over the parallax have about 2/3 each, a ray from the side
    of two nearly parallel ones has 1: the place's range is its alone, and its residual is 0
    whatever it is)."""
    lever = _leverage(point, poses)
    return lever is not None and bool(np.all(lever <= UNCONTROLLED))


def _leverage(point: np.ndarray, poses: np.ndarray) -> np.ndarray | None:
    """Each bearing's leverage in a landmark's place, ``J_i (J' J)^-1 J_i'`` (the hat matrix's
    diagonal, the bearings' sigmas equal); None where ``J' J`` is singular."""
    J, _ = _point_jacobian(point, poses)
    try:
        return np.einsum("ij,jk,ik->i", J, np.linalg.inv(J.T @ J), J)
    except np.linalg.LinAlgError:
        return None


def _residuals(point: np.ndarray, poses: np.ndarray, bearings: np.ndarray) -> np.ndarray:
    d = point[None, :] - poses[:, :2]
    return wrap(bearings - (np.arctan2(d[:, 1], d[:, 0]) - poses[:, 2]))


def _point_jacobian(point: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each bearing's derivative in the landmark's ``point`` ``(K, 2)``, and the squared ranges."""
    d = point[None, :] - poses[:, :2]
    q = np.einsum("ki,ki->k", d, d)
    return np.stack([-d[:, 1] / q, d[:, 0] / q], axis=1), q


def snooped(point: np.ndarray, poses: np.ndarray, bearings: np.ndarray, sigma: float, alpha: float = 0.01
            ) -> tuple[int, np.ndarray] | None:
    """The one bearing a landmark's place rests on that the others reject, and the place without
    it: Baarda's data snooping (1968) with each bearing's deleted residual, the landmark refitted
    on the others (:func:`refine`, the poses held) and the bearing predicted from there, over its
    variance ``sigma^2 (1 + J_i (J' J)^-1 J_i')``, against the chi-square at ``1 - alpha / K``
    (Bonferroni over the ``K`` bearings). Only bearings of leverage over 1/2 (``J_i (J' J)^-1
    J_i'``; a place's two coordinates share 2 among all) are tried: where many bearings hold a
    landmark no one of them moves it, and the gate judges each. None where no bearing is
    rejected, or fewer than :data:`AGREEING` would remain.

    Why: a misread bearing from the far side of a landmark seen a few times can carry its range
    alone, and the least squares then fit every bearing within the gate (a synthetic log with 5 %
    misread, seed 6: landmark 1, three true bearings and one misread from 105 m, 26 m off)."""
    k = len(bearings)
    if k <= AGREEING:
        return None
    lever = _leverage(point, poses)
    if lever is None:
        return None
    limit = chi2_quantile(1.0 - alpha / k, 1)
    worst: tuple[float, int, np.ndarray] | None = None
    for i in np.flatnonzero(lever > 0.5):
        others = np.arange(k) != i
        at = refine(point, poses[others], bearings[others])
        Jo, _ = _point_jacobian(at, poses[others])
        Ji, _ = _point_jacobian(at, poses[i:i + 1])
        try:
            var = sigma ** 2 * (1.0 + float(Ji[0] @ np.linalg.solve(Jo.T @ Jo, Ji[0])))
        except np.linalg.LinAlgError:
            continue
        t2 = float(_residuals(at, poses[i:i + 1], bearings[i:i + 1])[0] ** 2) / var
        if t2 > limit and (worst is None or t2 > worst[0]):
            worst = (t2, int(i), at)
    return None if worst is None else worst[1:]


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
        r = _residuals(x, poses, bearings)
        J, q = _point_jacobian(x, poses)
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
