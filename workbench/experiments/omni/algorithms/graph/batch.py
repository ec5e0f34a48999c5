"""``gtsam-batch``: Levenberg-Marquardt over the whole run from the starts ``--batch-starts``
names (:mod:`.starts`), the bearings regated at the answer, and marginal covariances for every
pose."""

from __future__ import annotations

from collections.abc import Callable

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.experiments.omni.algorithms import residuals
from workbench.experiments.omni.algorithms.graph import undecided
from workbench.experiments.omni.algorithms.graph.gating import (
    _bearing_test,
    gate_of,
    gated,
    gated_indices,
    robust_cost,
)
from workbench.experiments.omni.algorithms.graph.keyframes import (
    Keyframes,
    _lm_params,
    _pose,
    keyframes,
    poses_of,
    to_world,
)
from workbench.experiments.omni.algorithms.graph.landmarks import (
    AGREEING,
    CHANCE,
    _batch_graph,
    _Landmarks,
    chance_agreement,
    ray_chance,
    snooped,
)
from workbench.experiments.omni.algorithms.graph.marginals import marginal_blocks
from workbench.experiments.omni.algorithms.graph.relocation import _relocate, _tolerance
from workbench.experiments.omni.algorithms.graph.starts import Start, _best_start, fit, named_starts
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData


def batch(data: OmniData, cfg: OmniConfig, kf: Keyframes | None = None,
          starts: list[Start | Callable[[], Start]] | None = None) -> SlamEstimate:
    """Levenberg-Marquardt over the whole run; marginals for every pose.

    It starts from ``starts`` (default: those ``cfg`` names, :func:`named_starts`) in the order
    given, solving the next only while the last fit fails its chi-square test
    (:func:`_best_start`), re-gates each solved one against its own answer (:func:`_settle`) and
    keeps the one of the lowest :func:`robust_cost` on the data then (never the truth); ``start`` /
    ``start_costs`` in the answer say which won and what each one cost re-gated. The
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
    solved = _best_start(data, cfg, kf, starts)
    settled = {i: _settle(data, cfg, kf, *one, kept_out=starts[i].rejected if starts[i].final else set())
               for i, one in solved.items()}
    costs = {i: robust_cost(data, cfg, kf, one[0], one[1].inserted) for i, one in settled.items()}
    won = min(settled, key=lambda i: (costs[i], i))  # the first listed on a tie
    answers = {i: _answer(len(data.landmarks), E, one) for i, one in settled.items()}
    result, marks, rejected, first_seen, init_step, graph, lm_cov, covs = settled[won]
    poses, world, mean, _ = answers[won]
    chi2 = fit(graph, result, E, int(marks.inserted.sum()))
    return SlamEstimate("gtsam-batch", kf.steps.copy(), poses, world,
                        np.array([kf.steps[-1]]), mean[None], lm_cov[None], first_seen, init_step,
                        gated_bearings=gated_indices(data, kf, rejected), start=starts[won].name,
                        start_costs={starts[i].name: float(c) for i, c in costs.items()}, fit=chi2,
                        residuals=residuals.of_graph(graph, result, kf, marks.inserted, rejected, cfg.nis_gate or None),
                        undecided=undecided.between({i: starts[i].name for i in settled}, costs, won, chi2, answers))


def _answer(landmarks: int, E: int, settled: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A settled start's ``(poses, their world covariances, landmarks (NaN: unmapped), theirs)``."""
    result, marks, *_, lm_cov, covs = settled
    poses = poses_of(result, E)
    mean = np.full((landmarks, 2), np.nan)
    for lm in np.flatnonzero(marks.inserted):
        mean[lm] = result.atPoint2(L(int(lm)))
    return poses, to_world(covs, poses[:, 2]), mean, lm_cov


def _settle(data: OmniData, cfg: OmniConfig, kf: Keyframes, result: gtsam.Values, marks: _Landmarks,
            rejected: set[tuple[int, int]], first_seen: np.ndarray, init_step: np.ndarray,
            kept_out: set[tuple[int, int]] = frozenset()) -> tuple:
    """One start's solve re-gated against its own answer until the verdict stands (at most
    ``REGATE_ROUNDS`` rounds; :func:`batch`): ``(result, marks, rejected, first_seen, init_step,
    graph, lm_cov, covs)``.

    The starts are compared by their cost here, not at their first solve. Why: a start that still
    holds misreads it has not yet re-gated costs more at its first solve than one in a wrong basin
    that left them out with many good bearings: on MRCLAM 6 robot 1 with 2 % of the barcodes
    misread, the batch from the truth cost 15,153 at its first solve against 3,340-4,500 for
    iSAM2's, the grown graph's and dead reckoning's, and 529 once re-gated against their
    2,463-3,374 (0.14 m against 2.0-2.6 m; ``benchmarks/mrclam_misreads.py``).

    ``kept_out``: bearings no round takes back (``gnc``'s verdict, reached by the whole graph's
    evidence: re-gated at the marginals, which the misreads widen, they came back in, docs/long-logs.md)."""
    E = len(kf.steps)
    gating_on = gated(cfg)
    least = AGREEING if gating_on else 2
    # with a gate, a landmark two rays alone place leaves the map (its two bearings fit it exactly
    # whatever they are, so the rest of the answer is the same without it): two rays always meet
    result = _drop_unseen(kf, marks, rejected, result, least)
    graph = _batch_graph(data, kf, marks, rejected)
    covs, lm_cov = _batch_marginals(graph, result, E, marks.inserted)
    for _ in range(REGATE_ROUNDS if gating_on else 0):
        again = _regate(data, cfg, kf, result, covs, lm_cov, marks.inserted) | set(kept_out)
        rays = _rays(kf, marks)
        smoothed = poses_of(result, E)  # held through the round
        again, moved = _relocate(data, cfg, rays, marks, again, result, smoothed, _contradicted(kf, marks, result))
        again, cut = _snoop(data, rays, again, result, smoothed)
        again, ghosts = _ghosts(data, cfg, rays, again)
        if again == rejected and not moved and not cut and not ghosts:
            break
        rejected = again
        result = _drop_unseen(kf, marks, rejected, result, least)   # the ghosts too: every bearing of theirs left out
        graph = _batch_graph(data, kf, marks, rejected)
        result = gtsam.LevenbergMarquardtOptimizer(graph, result, _lm_params(100)).optimize()
        covs, lm_cov = _batch_marginals(graph, result, E, marks.inserted)
    return result, marks, rejected, first_seen, init_step, graph, lm_cov, covs


def _drop_unseen(kf: Keyframes, marks: _Landmarks, rejected: set[tuple[int, int]], result: gtsam.Values,
                 least: int = 2) -> gtsam.Values:
    """Take out of the map every landmark the gate left fewer than ``least`` bearings of (one ray
    does not fix a point: the system would be indeterminate; two fix it but nothing checks it)."""
    kept = np.zeros(len(marks.inserted), int)
    for e, (lms, _) in enumerate(kf.bearings):
        for lm in lms.tolist():
            kept[lm] += (e, lm) not in rejected
    out = gtsam.Values(result)
    for lm in np.flatnonzero(marks.inserted & (kept < least)):
        marks.inserted[lm] = False
        out.erase(L(int(lm)))
    return out


REGATE_ROUNDS = 3
"""How many times the batch re-gates every bearing against its own smoothed answer."""


def _rays(kf: Keyframes, marks: _Landmarks) -> dict[int, list[tuple[int, float]]]:
    """Each landmark in the map -> its bearings ``(keyframe, bearing)``."""
    rays: dict[int, list[tuple[int, float]]] = {}
    for e, (lms, bearings) in enumerate(kf.bearings):
        for lm, b in zip(lms.tolist(), bearings.tolist(), strict=True):
            if marks.inserted[lm]:
                rays.setdefault(lm, []).append((e, b))
    return rays


def _ghosts(data: OmniData, cfg: OmniConfig, rays: dict[int, list[tuple[int, float]]],
            rejected: set[tuple[int, int]]) -> tuple[set[tuple[int, int]], list[int]]:
    """Landmarks that misread ids alone made: every bearing of theirs left out (so
    :func:`_drop_unseen` takes them out of the map).

    A misread id (a barcode read wrong, a wrong association) hands an id a bearing of another
    landmark; an id never seen for real gets only such rays, pointing anywhere, and three of five
    of them meet within the gate's tolerance often enough (a synthetic log with 10 % misread: ids
    4, 13 and 71, never seen, mapped 91-117 m from anywhere). A landmark some of whose bearings the
    gate left out (rays that agree with nothing: the id carries misreads) is kept only where the
    rays that agree with it are more than chance: :func:`chance_agreement` under :data:`CHANCE`,
    the tolerance's share of the field of view the chance that one random ray agrees. A landmark
    whose every bearing agrees is not judged: without a misread there are no random rays."""
    p = ray_chance(_tolerance(data, cfg), data.fov)
    out, gone = set(rejected), []
    for lm, held in rays.items():
        left = sum((e, lm) in rejected for e, _ in held)
        if left and chance_agreement(len(held), len(held) - left, p) > CHANCE:
            gone.append(lm)
            out.update((e, lm) for e, _ in held)
    return out, gone


def _contradicted(kf: Keyframes, marks: _Landmarks, result: gtsam.Values) -> set[int]:
    """The landmarks in the map most of whose own bearings miss them at ``result`` by over 3 of the
    bearings' robust sigmas (:meth:`~workbench.estimation.consistency.Residuals.contradicted`, the
    reading :func:`workbench.experiments.omni.placed.contradicted` reports): their place is not theirs."""
    from workbench.estimation.consistency import Residuals

    _, lm_of, r2 = residuals.bearing_residuals(kf, result, marks.inserted)
    n = len(r2)
    return set(Residuals(np.full(n, "bearing"), r2, np.ones(n, int), np.ones(n, bool), {},
                         landmark=lm_of).contradicted())


def _snoop(data: OmniData, rays: dict[int, list[tuple[int, float]]], rejected: set[tuple[int, int]],
           result: gtsam.Values, smoothed: np.ndarray) -> tuple[set[tuple[int, int]], list[int]]:
    """Each landmark's one bearing its others reject (:func:`.landmarks.snooped`, from the
    smoothed poses) left out, the landmark moved to where the others put it (``result`` updated
    in place; the next solve starts from it)."""
    out, moved = set(rejected), []
    for lm, held in rays.items():
        kept = [(e, b) for e, b in held if (e, lm) not in out]
        if len(kept) <= AGREEING:
            continue
        poses = smoothed[[e for e, _ in kept]]
        found = snooped(np.asarray(result.atPoint2(L(lm)), float), poses, np.array([b for _, b in kept]),
                        data.sigma_bearing)
        if found is not None:
            out.add((kept[found[0]][0], lm))
            result.update(L(lm), gtsam.Point2(*found[1]))
            moved.append(lm)
    return out, moved


def _batch_marginals(graph: gtsam.NonlinearFactorGraph, result: gtsam.Values, E: int, inserted: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Every keyframe pose's ``(E, 3, 3)`` (body frame) and landmark's ``(N, 2, 2)`` marginal; NaN
    where GTSAM cannot compute them."""
    lm_cov = np.full((len(inserted), 2, 2), np.nan)
    try:
        marginals = gtsam.Marginals(graph, result)
        held = np.flatnonzero(inserted)
        blocks = marginal_blocks(marginals, [X(e) for e in range(E)] + [L(int(lm)) for lm in held])
        covs = np.array(blocks[:E])
        if len(held):
            lm_cov[held] = blocks[E:]
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
