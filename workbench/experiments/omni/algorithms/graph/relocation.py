"""Landmarks placed where their own bearings disagree, placed again: :func:`_relocate`, which the batch
runs after each solve, and iSAM2's landmarks that their later bearings outvote, placed again as the
bearings come (:func:`relocate`, run by :class:`.incremental._Incremental` on one landmark at a time).

Why: a landmark enters iSAM2 where its first held rays agree (:meth:`.landmarks._Landmarks.trusted`).
Where one of those is a misread id from elsewhere that alone gives the range, every true bearing
that comes after misses the place, and the gate (:meth:`.incremental._Incremental._consistent`)
leaves each out: the landmark stays wrong for the rest of the log, however many true bearings
say so (a synthetic log with 10 % misread ids, seed 1, landmark 122: one misread from 140 keyframes
before and three true rays from consecutive keyframes; iSAM2's map 7.5 m off, its bound 0.85 m, where the
batch's, which places landmarks again after each solve, is 0.44 m off). Here a landmark of which
:data:`AGREEING` bearings have been left out since it was last looked at is looked at again with the
batch's rule, from iSAM2's estimate: placed again by consensus over all its bearings where more of
them were left out than taken in and more agree on the new place, or where the new place explains
them better by the truncated squared error. If it moves, the bearings that agree with the new place
(each judged on its own) are the landmark's factors, the others left out, and the graph is solved
again by one damped LM pass from iSAM2's estimate with the landmark at its new place, on which iSAM2
is rebuilt (as at a run-away; the pass counts towards :data:`.incremental.PASS_BUDGET`, so the cost
stays bounded by the log's length times that budget)."""

from __future__ import annotations

import math
from typing import Any

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms.graph.gating import gate_of
from workbench.experiments.omni.algorithms.graph.keyframes import _lm_params, _pose, poses_of
from workbench.experiments.omni.algorithms.graph.landmarks import AGREEING, _Landmarks, _residuals, consensus
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData


def due(inc: Any, e: int, lm: int) -> bool:
    """Whether landmark ``lm`` is in the graph (a pass can take it out: :class:`.pruned._Pruned`) and
    due for a look at keyframe ``e``: at least :data:`AGREEING` of its bearings left out since the
    last look, twice as many after each look that moved nothing (so a landmark whose bearings the
    gate leaves out for another reason, a trajectory off, is looked at a logarithmic number of
    times), and the looks' LM solves so far within :data:`LOOK_BUDGET` graphs of the log's length."""
    return (lm in inc.points and inc.left_since.get(lm, 0) >= inc.look_after.get(lm, AGREEING)
            and inc.look_work <= LOOK_BUDGET * (e + 1))


LOOK_BUDGET = 40.0
"""The looks' LM solves, summed over their graphs' keyframes, at most this many times the log's
length so far: a bound on what they cost, linear in the log."""


def relocate(inc: Any, e: int, lm: int) -> bool:
    """Place ``lm`` again (:func:`_relocate`) from iSAM2's estimate at keyframe ``e``; where
    it moves, its factors made the bearings that agree with the new place, ``inc.rejected`` the
    others, and ``inc.start`` iSAM2's estimate with the landmark there (for the pass that follows).
    Returns whether it moved."""
    inc.left_since[lm] = 0
    inc.look_after[lm] = 2 * inc.look_after.get(lm, AGREEING)
    rays = inc.rays[lm]
    # the graph as it is, solved (damped LM from iSAM2's estimate): the place is judged from poses
    # that every factor has had its say on, and the move against this answer
    inc.look_work += 2 * (e + 1)
    try:
        stayed = gtsam.LevenbergMarquardtOptimizer(inc.everything, inc.isam.calculateEstimate(),
                                                   _lm_params(50)).optimize()
    except RuntimeError:
        return False
    values = gtsam.Values(stayed)
    smoothed = poses_of(values, e + 1)
    _, moved = _relocate(inc.data, inc.cfg, {lm: rays}, inc.marks, inc.rejected, values, smoothed)
    if not moved:
        return False
    point = np.asarray(values.atPoint2(L(lm)), float)
    # each ray judged at the new place on its own (not by its keyframe: one keyframe can hold a true
    # bearing of the landmark and a misread under its id, 159 deg apart)
    poses = smoothed[[k for k, _ in rays]]
    tolerance = _tolerance(inc.data, inc.cfg)
    ok = np.abs(_residuals(point, poses, np.array([b for _, b in rays]))) < tolerance
    reach = np.hypot(*(point - poses[ok, :2]).T)
    if not _plausible(reach, float(np.hypot(*(point - inc.points[lm]))), tolerance, inc.data.max_range):
        return False
    graph = gtsam.NonlinearFactorGraph()   # every factor but the landmark's bearings, then those that agree
    for i in range(inc.everything.size()):
        factor = inc.everything.at(i)
        if not (isinstance(factor, gtsam.BearingFactor2D) and factor.keys()[1] == L(lm)):
            graph.add(factor)
    for (k, b), agrees in zip(rays, ok, strict=True):
        if agrees:
            graph.add(inc.marks.factor(k, lm, b))
    # the data decide: the moved graph solved too, and the move kept only where it lowers the
    # truncated cost of every bearing of the map and the odometry
    try:
        moved_to = gtsam.LevenbergMarquardtOptimizer(graph, values, _lm_params(50)).optimize()
    except RuntimeError:
        return False
    if _cost(inc, graph, moved_to, tolerance) >= _cost(inc, inc.everything, stayed, tolerance):
        return False
    inc.everything = graph
    left = {(k, lm) for (k, _), agrees in zip(rays, ok, strict=True) if not agrees}
    inc.rejected = {p for p in inc.rejected if p[1] != lm} | left
    inc.points[lm] = np.asarray(moved_to.atPoint2(L(lm)), float)
    inc.start = moved_to
    inc.relocated.append((e, lm))
    return True


def _cost(inc: Any, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, tolerance: float) -> float:
    """The odometry's chi-square in ``graph`` at ``values`` plus every bearing of every landmark in
    the map, each squared residual capped at ``tolerance``'s square (MSAC: Torr and Zisserman 2000;
    a bearing left out costs the cap, as one that misses by more), over the bearings' variance."""
    odometry = gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        factor = graph.at(i)
        if not isinstance(factor, gtsam.BearingFactor2D):
            odometry.add(factor)
    total = 2.0 * odometry.error(values)
    for lm, rays in inc.rays.items():
        if not values.exists(L(lm)):
            continue
        poses = np.array([_pose(values.atPose2(X(k))) for k, _ in rays])
        r = _residuals(np.asarray(values.atPoint2(L(lm)), float), poses, np.array([b for _, b in rays]))
        total += float(np.minimum(r**2, tolerance**2).sum()) / inc.data.sigma_bearing**2
    return total


def _plausible(reach: np.ndarray, moved: float, tolerance: float, max_range: float) -> bool:
    """Whether a new place is worth a pass: no farther from the poses whose rays agree with it than
    :data:`REACH` times what the sensor sees (``max_range``; the poses are estimates: a synthetic
    drive's landmark seen from 30 m is placed 30.4 m from them; MRCLAM 6 robot 4 told a turn sigma
    of 1.8 deg, its poses a metre off, found 21 of landmark 12's 80 bearings agreeing 58 m away,
    where nothing is seen past 6 m), and moved by more than the gate already allows (``tolerance``
    times the median range: a landmark 3 cm from where it was, 3 m away, needs no pass)."""
    return bool(reach.size and reach.max() <= REACH * max_range and moved > tolerance * float(np.median(reach)))


REACH = 1.5
"""How far past the sensor's range (a factor) a new place may be from the poses that see it."""


def _tolerance(data: OmniData, cfg: OmniConfig) -> float:
    """How far (rad) a ray may be from a landmark's place and agree with it: the gate's."""
    return math.sqrt(max(float(gate_of(cfg)(data.sigma_bearing ** 2)), 0.0)) * data.sigma_bearing



def _relocate(data: OmniData, cfg: OmniConfig, rays: dict[int, list[tuple[int, float]]], marks: _Landmarks,
              rejected: set[tuple[int, int]], result: gtsam.Values, smoothed: np.ndarray,
              suspect: set[int] = frozenset()) -> tuple[set[tuple[int, int]], list[int]]:
    """Landmarks placed where their own bearings disagree, moved to where they agree.

    A landmark enters from the first rays that agree (:func:`.landmarks.consensus`); where those
    were misread ids (another landmark's bearings under its id) it sits where they meet, and the
    gate then leaves out its own bearings, each one on its own too far from that place (a
    synthetic log with 10 % of the ids misread: landmark 32, 49 true bearings of 55, 62 m off).
    Here every landmark whose bearings that miss it by more than the gate's tolerance could, capped,
    gain the chi-square below (two of them or more: where least squares hold a landmark, capping
    the bearings it misses gains at most the tolerance's square each) is placed again by consensus
    over all its bearings, from the smoothed poses, and moves there (``result``
    updated in place; those bearings taken in and the rest left out; the next solve starts from
    it) where

    * the gate left more than half its bearings out, or most of them miss it by over 3 robust
      sigmas (``suspect``, :func:`_contradicted`: the gate, which weighs the pose's and the
      landmark's covariances too, can keep what misses; landmark 52 of that log, 5 of its 9
      bearings missed and 3 gated, sat 61 m off), and more of them agree on the new place than
      were taken in at the old: RANSAC's reading (Fischler and Bolles 1981), the place most rays
      support, not the first few; or
    * the new place explains its bearings better by the truncated squared error (MSAC: Torr and
      Zisserman 2000; each bearing's squared residual, capped at the tolerance's square, so an
      outlier costs the same wherever it points), by more than the 99 % chi-square of the two
      coordinates a place has (:data:`MOVE_GAIN`). Landmark 87 of that log: 5 true bearings,
      their rays 14 deg apart, and one misread from 78 m away; least squares put it 44 m off
      where the misread meets four of the five, which miss by up to 4.6 sigmas, none gated.

    The consensus here takes pairs of rays whose parallax is twice the tolerance (two rays
    within it cannot then meet at infinity), not the insertion's ``min_parallax``: 87's own rays
    never have the 15 deg a log's landmarks enter with, and the cost, not the parallax, judges
    the place. On the synthetic drives without misreads, Student-t bearings, blind stretches
    or a misstated odometry, and on MRCLAM 6 and the paper's simulation, nothing moves (measured:
    the maps to the last digit)."""
    tolerance = _tolerance(data, cfg)
    gain_needed = chi2_quantile(MOVE_GAIN, 2) * data.sigma_bearing ** 2
    out, moved = set(rejected), []
    for lm, held in rays.items():
        if len(held) < AGREEING:
            continue
        left = sum((e, lm) in rejected for e, _ in held)
        poses = smoothed[[e for e, _ in held]]
        bearings = np.array([b for _, b in held])
        here = _residuals(np.asarray(result.atPoint2(L(lm)), float), poses, bearings)
        outvoted = 2 * left > len(held) or lm in suspect
        if not outvoted and np.sum(np.abs(here) >= tolerance) * tolerance ** 2 <= gain_needed:
            continue  # where least squares hold it, capping the bearings it misses gains at most this
        found = consensus(poses, bearings, tolerance, min(marks.min_parallax, 2.0 * tolerance))
        if found is None:
            continue
        point, agree = found
        gain = _truncated(here, tolerance) - _truncated(_residuals(point, poses, bearings), tolerance)
        if not (outvoted and int(agree.sum()) > len(held) - left) and gain <= gain_needed:
            continue
        result.update(L(lm), gtsam.Point2(*point))
        for (e, _), ok in zip(held, agree, strict=True):
            (out.discard if ok else out.add)((e, lm))
        moved.append(lm)
    return out, moved



MOVE_GAIN = 0.99
"""The chi-square probability (2 degrees of freedom: a place's coordinates) the truncated squared
error must fall by for a landmark to move on it alone (:func:`_relocate`)."""


def _truncated(r: np.ndarray, tolerance: float) -> float:
    """MSAC's cost of residuals ``r`` (rad): each squared, capped at ``tolerance`` squared."""
    return float(np.sum(np.minimum(np.square(r), tolerance ** 2)))
