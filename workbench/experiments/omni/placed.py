"""The landmarks a map holds that its data cannot place: those whose depth along the rays that saw
them the bearings do not decide (seen from one side, along the direction of travel, or twice from
nearly the same place), by the estimator's own covariance, with no truth.

A landmark is *not placed* where its 95 % confidence ellipse (the final map's marginal, the
2-d chi-square's 95 % point, 2.45 sigma along its major axis) reaches further than the landmark is
from the poses that saw it (the median range, from the estimator's own poses at those bearings):
the data then put it anywhere from at the robot to twice as far, which is no place. The reading is
the estimator's own (an estimator whose noise is too narrow holds too small an ellipse: its
diagnosis says that), and the landmark's estimate is kept, marked: the user decides.

A landmark is *contradicted* where its own bearings reject the place the estimator gave it: the
median of their whitened residuals at the answer is beyond :data:`MISS` sigma (more than half of
them miss it by that; a Gaussian leaves 0.27 % out there, MRCLAM's heavy tail 20-24 %), of at least
:data:`MIN_SEEN` bearings. A median is what a breakdown point of one half allows: a place most
of the data reject is the misreads' or a wrong start's, not the landmark's (a misread id's ghost: a
landmark put where a few bearings meant for others happen to cross, its own gated away). A smoother
gives each bearing's residual at its answer (``Residuals.landmark``); a filter's innovations were
judged at other states, so it is read for smoothers alone.
"""

from __future__ import annotations

import math

import numpy as np

from workbench.estimation.consistency import MISS_LEAST, MISS_SIGMAS
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData

REACH = math.sqrt(-2.0 * math.log(0.05))   # the 95 % ellipse's semi-axes in sigmas (2-d: 2.448)
MISS, MIN_SEEN = MISS_SIGMAS, MISS_LEAST   # (a bearing this many sigmas off misses; fewer bearings: no median)
UNMAPPED_SHOWN = 8                          # ids named in the report's line (all in the metrics)


def unplaced(data: OmniData, est: SlamEstimate) -> dict | None:
    """The landmarks of ``est``'s final map the data cannot place (the module's text): ``ids``, and
    for each the ratio of its ellipse's reach (semi-major axis, 95 %) to its range (``reach``, by id
    as a string: over 1 is not placed); ``unmapped``: the ids seen at least :data:`MIN_SEEN` times
    that the map does not hold at all (an estimator that waits for rays that check each other, or
    leaves a ghost out, says so rather than place them); None where the map has no covariances."""
    cov = est.final_map_cov
    if cov is None or est.pose is None or not len(est.map_mean):
        return None
    mean = est.final_map
    steps = np.asarray(est.steps, int)
    at = np.clip(np.searchsorted(steps, data.meas_step), 0, len(steps) - 1)
    seen_from = np.asarray(est.pose, float)[at, :2]
    lm = np.asarray(data.meas_lm, int)
    rows = np.isfinite(seen_from).all(axis=1) & np.isfinite(mean[lm]).all(axis=1)
    seen = np.bincount(lm, minlength=len(mean))
    unmapped = {"unmapped": [int(data.landmark_ids[i]) for i in np.flatnonzero((seen >= MIN_SEEN)
                                                                              & ~np.isfinite(mean).all(axis=1))]}
    if not rows.any():
        return {"ids": [], "reach": {}, **_rejected(est, data.landmark_ids), **unmapped}
    dist = np.hypot(*(seen_from[rows] - mean[lm[rows]]).T)
    order = np.lexsort((dist, lm[rows]))           # each landmark's ranges together, sorted
    lms, first, count = np.unique(lm[rows][order], return_index=True, return_counts=True)
    d = dist[order]
    rng = 0.5 * (d[first + (count - 1) // 2] + d[first + count // 2])   # each one's median range
    c = cov[lms]
    ok = np.isfinite(c).all(axis=(1, 2)) & (rng > 0)
    major = np.linalg.eigvalsh(0.5 * (c[ok] + c[ok].transpose(0, 2, 1)))[:, -1]
    reach = REACH * np.sqrt(np.clip(major, 0.0, None)) / rng[ok]
    ratio = {str(int(data.landmark_ids[i])): float(r) for i, r in zip(lms[ok], reach, strict=True)}
    return {"ids": [int(k) for k, r in ratio.items() if r > 1.0], "reach": ratio,
            **_rejected(est, data.landmark_ids), **unmapped}


def _rejected(est: SlamEstimate, ids: np.ndarray) -> dict:
    found = contradicted(est, ids)
    return {} if found is None else {"contradicted": found["ids"], "missed": found["missed"]}


def contradicted(est: SlamEstimate, ids: np.ndarray) -> dict | None:
    """The landmarks of a smoother's map its own bearings reject (the module's text): ``ids``, and
    for each landmark with :data:`MIN_SEEN` bearings the share of them beyond :data:`MISS` sigma
    (``missed``, by id as a string: over a half is contradicted); None without per-landmark residuals."""
    res = getattr(est, "residuals", None)
    if res is None or res.landmark is None:
        return None
    missed = {str(int(ids[i])): v for i, v in res.missed().items() if i < len(ids)}
    return {"ids": [int(ids[i]) for i in res.contradicted() if i < len(ids)], "missed": missed}


def describe(found: dict | None) -> str:
    """One line of what :func:`unplaced` found ('' where every landmark is placed and none contradicted)."""
    if not found:
        return ""
    out = []
    ids = found["ids"]
    if ids:
        reach = ", ".join(f"{found['reach'][str(i)]:.1f}" for i in ids)
        out.append(f"the data cannot place id {ids[0]} (its 95 % ellipse {reach}x its range): too little parallax"
                   if len(ids) == 1 else
                   f"the data cannot place ids {', '.join(map(str, ids))} (their 95 % ellipses {reach}x their "
                   "ranges): too little parallax")
    bad = found.get("contradicted") or []
    if bad:
        shares = ", ".join(f"{100 * found['missed'][str(i)]:.0f} %" for i in bad)
        one = len(bad) == 1
        out.append(f"{'id' if one else 'ids'} {', '.join(map(str, bad))} contradicted by {'its' if one else 'their'} "
                   f"own bearings ({shares} over {MISS:g} sigma off): misread ids or a wrong basin")
    gone = found.get("unmapped") or []
    if gone:
        shown = ", ".join(map(str, gone[:UNMAPPED_SHOWN])) + (", ..." if len(gone) > UNMAPPED_SHOWN else "")
        out.append(f"{len(gone)} {'id' if len(gone) == 1 else 'ids'} seen {MIN_SEEN}+ times not mapped ({shown}): "
                   "their bearings place them nowhere the estimator trusts")
    return "; ".join(out)
