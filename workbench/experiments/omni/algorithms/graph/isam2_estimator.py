"""``isam2``, the estimator: :class:`.incremental._Incremental` with iSAM2 updated at every keyframe,
read as a causal estimator (the newest pose and its marginal at each keyframe) and as a smoother
(its whole trajectory and map at the end, and its residuals there). With a gate on, its LM passes
re-gate every bearing at their answer (:class:`.pruned._Pruned`)."""

from __future__ import annotations

import functools
import math

import numpy as np
from gtsam.symbol_shorthand import X

from workbench.experiments.omni.algorithms import residuals
from workbench.experiments.omni.algorithms.graph.gating import gated, gated_indices
from workbench.experiments.omni.algorithms.graph.incremental import _Incremental
from workbench.experiments.omni.algorithms.graph.keyframes import Keyframes, keyframes, to_world
from workbench.experiments.omni.algorithms.graph.landmarks import _batch_graph
from workbench.experiments.omni.algorithms.graph.marginals import (
    MAP_FULL,
    _landmark_marginal,
    _marginal,
    _point_of,
    read_map,
)
from workbench.experiments.omni.algorithms.graph.pruned import _Pruned
from workbench.experiments.omni.algorithms.graph.relocation import REACH
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData


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
    gating_on = gated(cfg)
    inc = (_Pruned if gating_on else _Incremental)(data, cfg, kf)
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
    smoothed = inc.estimate()[0]
    far = out_of_reach(data, inc.rays, map_mean[-1], smoothed) if E else []
    if far:   # not mapped: the data do not place them (:func:`out_of_reach`)
        map_mean[-1][far], map_cov[-1][far] = np.nan, np.nan
    for mean, cov in zip(map_mean, map_cov, strict=True):  # an earlier reading's overflow, likewise
        off = np.isinf(mean).any(axis=1) | np.isinf(cov).any(axis=(1, 2))
        mean[off], cov[off] = np.nan, np.nan
    remarks = _remarks(data, kf, inc) + ([f"iSAM2 could not place landmark(s) {', '.join(map(str, far))}: its "
                                          "answer puts them beyond the sensor's reach from every pose that saw "
                                          "them; left out of its map"] if far else [])
    return SlamEstimate("isam2", kf.steps.copy(), poses, to_world(covs, poses[:, 2]), np.array(map_steps),
                        np.array(map_mean), np.array(map_cov), inc.first_seen, inc.init_step,
                        failures=inc.failures, lm_passes=inc.passes,
                        gated_bearings=gated_indices(data, kf, inc.rejected),
                        smoothed=smoothed, residuals=_held_residuals(data, cfg, kf, inc),
                        remarks=remarks)


def out_of_reach(data: OmniData, rays: dict[int, list[tuple[int, float]]], points: np.ndarray,
                 poses: np.ndarray) -> list[int]:
    """The landmarks of a final map ``points (N, 2)`` placed farther than :data:`.relocation.REACH`
    times the sensor's range (``max_range``) from every pose ``poses (E, 3)`` that saw it (``rays``:
    each landmark's ``(keyframe, bearing)``, taken or left out): a place the sensor could not have
    seen it from, so the data do not fix where it is. Why: where iSAM2 is given up, or its
    Gauss-Newton steps run a landmark off along near-parallel rays, its map read 68 m to
    4e27 m after alignment on 3 of 20 MRCLAM 6 logs with 1-2 % misread ids
    (``benchmarks/mrclam_misreads.py``); a map is then the landmarks it placed, and it says which it
    could not, rather than give those places as an answer (issue 36); one run off to infinity (robot 5
    at 2 % seed 1 overflowed, and the run failed its check) is such a landmark too. The rule is relocation's for
    a move (:func:`.relocation._plausible`)."""
    far = []
    for lm in np.flatnonzero(~np.isnan(points).all(axis=1)).tolist():
        if not np.isfinite(points[lm]).all():   # run off to infinity (a float overflow)
            far.append(lm)
            continue
        seen_from = [k for k, _ in rays.get(lm, []) if k < len(poses)]
        if seen_from and np.hypot(*(points[lm] - poses[seen_from, :2]).T).min() > REACH * data.max_range:
            far.append(lm)
    return far


def _remarks(data: OmniData, kf: Keyframes, inc: _Incremental) -> list[str]:
    """What went wrong in iSAM2 that its numbers do not show: where it was given up (its run-away
    passes past their budget, :data:`.incremental.PASS_BUDGET`, or an update no pass could mend),
    after which its answer is the last LM pass's carried on with the odometry; and the landmarks it
    placed again where their later bearings outvoted the place they entered at (:mod:`.relocation`)."""
    moved = ", ".join(f"{lm} at {data.t[kf.steps[e]] - data.t[0]:.0f} s" for e, lm in inc.relocated)
    out = [f"iSAM2 placed {len(inc.relocated)} landmark(s) again ({moved}): their later bearings outvoted the "
           "places they had entered at (misread ids?)"] if inc.relocated else []
    if inc.isam is not None:
        return out
    at = inc.done if inc.gave_up is None else inc.gave_up
    return out + [f"iSAM2 gave up at {data.t[kf.steps[at]] - data.t[0]:.0f} s: after {inc.passes} damped LM pass(es) "
            "it kept running away; from there on its answer is the last pass's carried on with the odometry"]


def _held_residuals(data: OmniData, cfg: OmniConfig, kf: Keyframes, inc: _Incremental):
    """iSAM2's residuals at the answer it holds at the end (:mod:`.residuals`), over the graph of
    its landmarks and the bearings it kept (where it gave up, at the last pass's answer carried on with
    the odometry, which is what it returns)."""
    values = inc.values()
    graph = _batch_graph(data, kf, inc.marks, inc.rejected)
    try:
        return residuals.of_graph(graph, values, kf, inc.marks.inserted, inc.rejected, cfg.nis_gate or None)
    except RuntimeError:  # a variable the graph holds that the answer does not
        return None


