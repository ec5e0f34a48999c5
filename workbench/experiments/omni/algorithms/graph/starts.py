"""Where the batch starts: dead reckoning with landmarks triangulated from it, iSAM2's or the
EKF's answer, or the graph grown keyframe by keyframe with LM passes; each solved in turn until
one's fit passes its chi-square test (``FIT_TEST``), the lowest cost kept."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms.graph.gating import gate_of, gated, robust_cost
from workbench.experiments.omni.algorithms.graph.incremental import _Incremental
from workbench.experiments.omni.algorithms.graph.isam2_estimator import isam2
from workbench.experiments.omni.algorithms.graph.keyframes import Keyframes, _lm_params
from workbench.experiments.omni.algorithms.graph.landmarks import _batch_graph, _Landmarks
from workbench.experiments.omni.algorithms.graph.pruned import _Pruned
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData


def fit(graph: gtsam.NonlinearFactorGraph, result: gtsam.Values, poses: int, landmarks: int) -> tuple[float, int]:
    """The least-squares fit's chi-square: twice the graph's error at its answer (every factor's
    squared whitened residual: the prior, the odometry, the bearings kept) and its degrees of
    freedom, the residuals less the unknowns (``3 poses + 2 landmarks``). With the noise the model
    says and the right minimum it is chi-square with those degrees of freedom (the residual sum of
    squares of a linear(ised) least-squares fit: Bar-Shalom, Li, Kirubarajan, sec. 3.4); a wrong
    basin or a wrong noise model puts it far above. Readings: the bearings a gate left out are not
    counted (their test is the gate's), which biases it low by a little where the gate cut the
    tail of good ones (0.99: 1 % of them). A robust bearing factor (``--huber``, ``--batch-huber``)
    counts its Gaussian's squared residual, not its kernel's loss: the test is of the noise model,
    and a loss that grows linearly is no chi-square (it would pass a wrong basin more easily)."""
    chi2, residuals = 2.0 * float(graph.error(result)), 0
    robust = None   # whether the bearings are robust (they share one kernel): read off the first
    for i in range(graph.size()):
        f = graph.at(i)
        residuals += f.dim()
        if robust is None and isinstance(f, gtsam.BearingFactor2D):
            robust = isinstance(f.noiseModel(), gtsam.noiseModel.Robust)
        if robust and isinstance(f, gtsam.BearingFactor2D):   # its kernel's loss out, its Gaussian's in
            r = f.noiseModel().noise().whiten(f.unwhitenedError(result))
            chi2 += float(r @ r) - 2.0 * f.error(result)
    return chi2, int(residuals - 3 * poses - 2 * landmarks)


@dataclass
class Start:
    """Where the batch starts: ``poses (E, 3)`` at the keyframes, ``landmarks (N, 2)`` (NaN:
    triangulate from the poses), and the bearings ``(keyframe, landmark)`` that whatever made
    the start left out (its gate; the batch leaves them out too until it re-gates; ``final``: through
    the re-gating too, a verdict reached over the whole graph: ``gnc``'s)."""

    name: str
    poses: np.ndarray
    landmarks: np.ndarray
    rejected: set[tuple[int, int]]
    final: bool = False


@dataclass(frozen=True)
class Refinement:
    """A start made from a start already solved (``gnc``, from the cheapest: :func:`_best_start`):
    ``make(solved)``, ``solved`` that start's ``(result, marks, rejected, ...)``."""

    make: Callable[[tuple], Start]

    def __call__(self, solved: tuple) -> Start:
        return self.make(solved)


GROWN_EVERY = 20.0
"""s: the grown start's LM period where ``lm_every`` is 0 (iSAM2 without passes)."""


def own_start(data: OmniData, cfg: OmniConfig, kf: Keyframes, name: str | None = None) -> Start:
    """The batch's own start ``name`` (default: ``grown`` with ``lm_every > 0``, else
    ``odometry``): dead reckoning, or the graph grown with its LM passes (each re-gating the
    bearings at its answer where a gate is on: :class:`_Pruned`)."""
    name = name or ("grown" if cfg.lm_every > 0.0 else "odometry")
    if name == "grown":
        grown = cfg if cfg.lm_every > 0.0 else dataclasses.replace(cfg, lm_every=GROWN_EVERY)
        gating_on = gated(cfg)
        inc = (_Pruned if gating_on else _Incremental)(data, grown, kf, solver=False)
        for e in range(len(kf.steps)):
            inc.step(e)
        return Start("grown", *inc.estimate(), inc.rejected)
    if name != "odometry":
        raise ValueError(f"the batch's own starts are odometry and grown, not {name!r}")
    return Start("odometry", kf.dead_reckoning, np.full((len(data.landmarks), 2), np.nan), set())


def named_starts(data: OmniData, cfg: OmniConfig, kf: Keyframes,
                 made: dict[str, Callable[[], SlamEstimate]] | None = None) -> list[Callable[[], Start] | Refinement]:
    """The starts ``--batch-starts`` names, in order, each as a function that makes it (the batch
    makes only those it solves): the batch's own (:func:`own_start`) and other estimators' answers
    (:func:`start_from`), those made by ``made[name]()`` where given (a run's shared estimate),
    else run here; ``gnc``, graduated non-convexity from the cheapest start solved before it
    (:func:`.gnc.refine`)."""
    def run(name: str) -> SlamEstimate:
        if made and name in made:
            return made[name]()
        if name == "isam2":
            return isam2(data, cfg, kf)
        from workbench.experiments.omni.algorithms import ekf

        return ekf.run(data, cfg, "clone", "ekf", False)

    def make(name: str) -> Callable[[], Start] | Refinement:
        if name == "gnc":
            from workbench.experiments.omni.algorithms.graph import gnc

            return Refinement(lambda solved: Start("gnc", *gnc.refine(data, cfg, kf, *solved), final=True))
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


def _best_start(data: OmniData, cfg: OmniConfig, kf: Keyframes,
                starts: list[Start | Callable[[], Start] | Refinement]) -> dict[int, tuple]:
    """LM from the starts in the order given (one given as a function is made when it is reached;
    ``starts`` then holds it) until one ends with a fit its chi-square does not reject
    (:func:`plausible`); the rest are not solved, but for a ``gnc``, which refines the cheapest start
    solved before it (by :func:`.gating.robust_cost` at its LM answer) whatever their fits, and whose
    own fit ends no search (a fit over the bearings GNC kept passes by its own verdict). Returns the
    solved ones by index (the batch compares them by their :func:`.gating.robust_cost` once
    re-gated: :func:`.batch._settle`).

    Why: solving from every start cost a full LM solve of the whole run each (two of a long log's
    three solves, measured), though a fit that passes its test needs no second opinion. Where it
    fails (a wrong basin: a mirrored trajectory's is many times its degrees of freedom; or a wrong
    noise model), the next start is solved too and the lower cost on the data kept, as before.
    Why the cheapest, not the one just before: on MRCLAM 6 robot 4 with 1 % misread ids (seed 0)
    GNC from iSAM2's answer, a wrong basin whose fit passes once GNC has dropped what contradicts it,
    ended 3.04 m off at a cost of 1,789; from the grown start's (1,851 before GNC) 0.45 m off at 1,228.
    """
    solved: dict[int, tuple] = {}
    costs: dict[int, float] = {}  # the data's truncated cost at each start's LM answer, where a gnc follows
    refining = any(isinstance(s, Refinement) for s in starts)
    passed = False
    for i, start in enumerate(starts):
        refines = isinstance(start, Refinement)  # gnc: from the cheapest start solved before it
        if (passed and not refines) or (refines and not costs):
            continue
        if refines:
            start = starts[i] = start(solved[min(costs, key=lambda j: (costs[j], j))])
        elif callable(start):  # made only when it is needed
            start = starts[i] = start()
        values, marks, rejected, first_seen, init_step = _prepare(data, cfg, kf, start)
        graph = _batch_graph(data, kf, marks, rejected)
        result = gtsam.LevenbergMarquardtOptimizer(graph, values, _lm_params(100)).optimize()
        solved[i] = (result, marks, rejected, first_seen, init_step)
        if not refines:  # a fit over what GNC kept is GNC's verdict, not a test: it ends no search
            passed = plausible(*fit(graph, result, len(kf.steps), int(marks.inserted.sum())))
            if refining:
                costs[i] = robust_cost(data, cfg, kf, result, marks.inserted)
    return solved


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
    gating_on = gated(cfg)
    marks = _Landmarks.of(data, cfg, huber=cfg.batch_huber or None)
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
            if preset is None and gating_on and mapped.any():
                s2 = 2.0 * float(sigma) ** 2
                tolerance = math.sqrt(max(float(threshold(s2)), 0.0) * s2)
            _, point = marks.observe(e, lm, b, lambda k: start.poses[k], preset, tolerance, sigma=float(sigma))
            if point is None:
                continue
            values.insert(L(lm), point)
            init_step[lm] = kf.steps[e]
    return values, marks, set(start.rejected) | set(marks.outliers), first_seen, init_step
