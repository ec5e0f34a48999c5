"""**Evaluate**: a run's errors on its grid, what the recording draws of them, and what the
metrics JSON holds beyond the metrics (:mod:`.metrics`, which score every estimate).

Every estimator is scored on one grid of steps: the graph's keyframes (every bearing epoch,
and at least one per ``keyframe_every`` seconds), where all of them have an estimate.
Errors are ``truth - estimate`` with the heading wrapped; "after settling" means from
``settle`` seconds on (the paper's claims are for the settled filter, after the first loop).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from workbench.core.experiment import RunSummary as Summary
from workbench.estimation import consistency, metrics
from workbench.estimation.angles import wrap
from workbench.experiments.omni import placed, survey
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.run import RunResult
from workbench.experiments.omni.scenario import OmniData
from workbench.metrics import truthfree

if TYPE_CHECKING:
    from workbench.experiments.omni.algorithms import graph


def on_grid(est: SlamEstimate, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The estimate's poses and covariances at the grid's steps (NaN where it has none)."""
    where = np.searchsorted(est.steps, grid)
    where = np.clip(where, 0, len(est.steps) - 1)
    hit = est.steps[where] == grid
    pose = np.where(hit[:, None], est.pose[where], np.nan)
    cov = est.cov[where] if est.cov is not None else np.full((len(grid), 3, 3), np.nan)
    cov = np.where(hit[:, None, None], cov, np.nan)
    return pose, cov


def smoothed_on_grid(est: SlamEstimate, grid: np.ndarray) -> np.ndarray:
    """A smoother's whole trajectory as held at the end (``est.smoothed``) at the grid's steps."""
    return on_grid(SlamEstimate(est.name, est.steps, est.smoothed), grid)[0]


def pose_errors(truth: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``truth - estimate`` per row: x, y (m), heading (rad, wrapped)."""
    e = truth - pose
    e[:, 2] = wrap(e[:, 2])
    return e


def pose_nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """NEES of the pose (3 dof; any dimension the rows have, a position's 2) per row; NaN where
    either is unknown or the covariance singular."""
    out = np.full(len(err), np.nan)
    ok = np.isfinite(err).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    if ok.any():
        c = cov[ok]
        good = np.linalg.det(c) > 0
        idx = np.flatnonzero(ok)[good]
        out[idx] = metrics.nees(err[idx], cov[idx])
    return out


TRUTH_COVERAGE = 0.9
"""The share of the grid's steps with a true pose that the Cramér-Rao bounds need."""


def bounds(data: OmniData, cfg: OmniConfig, keyframes: graph.Keyframes | None = None) -> dict:
    """The run's Cramér-Rao variances (:func:`.bounds.variances`): per delay (0 filtering, inf
    smoothing) position and heading at every grid step, and the map; none where the bearings come
    from images (their noise is the image stage's, not the model's) or the log's truth is not a
    track: the bound is linearised at the true poses, so it needs them (heading too) at
    ``TRUTH_COVERAGE`` of the grid's steps at least (MRCLAM robot 4's short Vicon gaps are
    interpolated: :func:`.bounds._truth`); a sparse fix now and then, or positions alone, gives none;
    nor does a map without the true place of every landmark seen, nor a noise so large that the
    bound's systems are numerically singular (a speed noise of 5e5 m/s: the efficiencies are then
    not given, the run goes on)."""
    if cfg.from_images or np.isfinite(data.truth[data.grid]).all(axis=1).mean() < TRUTH_COVERAGE:
        return {}
    if not np.isfinite(data.landmarks[np.unique(data.meas_lm)]).all():
        return {}
    from workbench.experiments.omni import bounds as omni_bounds  # GTSAM, loaded where a bound is computed
    from workbench.experiments.omni.algorithms import graph
    from workbench.experiments.omni.run import assumes

    # (the estimators' keyframes carry the noise they were told; the bound is the data's own)
    kf = keyframes if keyframes is not None and not assumes(cfg) else graph.keyframes(data, cfg)
    try:
        return omni_bounds.variances(data, kf, {0.0, float("inf")})
    except (np.linalg.LinAlgError, RuntimeError):  # a noise so large the information is numerically nought
        return {}


@dataclass
class RunSummary(Summary):
    """What a Monte Carlo worker sends back beside the metrics: the errors, own sigmas and NEES on
    the grid (run 0's are drawn), the bounds (their curves over runs are drawn), what the image
    stage and the real log's reading report."""

    t: np.ndarray
    errors: dict[str, np.ndarray]
    sigmas: dict[str, np.ndarray]
    nees: dict[str, np.ndarray]
    images: dict | None = None
    delays: dict[str, float] = field(default_factory=dict)  # each estimator's delay (its bound)
    repairs: dict = field(default_factory=dict)  # what the real data needed to be read (omni.real)
    bounds: dict = field(default_factory=dict)  # delay -> {position, heading} (G,) variances; "map" (N,)
    reference: str | None = None  # no truth: ``errors`` are departures from this smoother, ``nees`` disagreements
    survey: dict[str, dict] = field(default_factory=dict)  # each map against the landmark survey (:mod:`.survey`)
    unplaced: dict[str, dict] = field(default_factory=dict)  # the landmarks each map cannot place (:mod:`.placed`)


def summarise(result: RunResult, cfg: OmniConfig, run: int) -> RunSummary:
    """Errors, own sigmas and NEES on the grid (signed: what the recording draws), the bounds.

    A log without the robot's truth has the run's smoother as the reference instead
    (:func:`.truthfree.smoother`): ``errors`` are each estimate's departure from it (the smoother's
    pose minus the estimate's) and ``nees`` each causal estimator's disagreement with it
    (:func:`~workbench.estimation.consistency.disagreement`, 3 dof, chi-square where both are
    consistent): where a filter and the smoother part ways, with no truth."""
    data, grid = result.data, result.grid
    truth = data.truth[grid]
    reference = None
    if not np.isfinite(truth).any():
        reference = truthfree.smoother(result.estimators, result.estimates)
    ref = on_grid(result.estimates[reference], grid) if reference is not None else None
    errs, sig, nees = {}, {}, {}
    for name, est in result.estimates.items():
        pose, cov = on_grid(est, grid)
        sig[name] = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
        if ref is None:
            errs[name] = e = pose_errors(truth, pose)
            nees[name] = pose_nees(e, cov)
        else:
            errs[name] = pose_errors(ref[0], pose)
            causal = name in result.estimators and result.estimators[name].causal
            nees[name] = (consistency.disagreement(pose, cov, *ref, angles=(2,)) if causal and name != reference
                          else np.full(len(grid), np.nan))
    delays = {n: result.estimators[n].delay for n in result.estimates if n in result.estimators}
    crb = result.shared("bounds", lambda: bounds(data, cfg, result.keyframes))
    mapped = {}
    for name, est in result.estimates.items():
        found = survey.compare(est.final_map, data.landmarks, data.landmark_ids) if len(est.final_map) else None
        if found is not None:
            mapped[name] = found
    loose = {n: u for n, est in result.estimates.items() if (u := placed.unplaced(data, est)) is not None}
    return RunSummary(run, data.t[grid], errs, sig, nees, result.images.stats if result.images is not None else None,
                      delays, dict(data.repairs or {}), crb, reference, mapped, loose, failed=dict(result.failed))


def bound_kind(delay: float) -> str:
    """The bound an estimator using ``delay`` s of data after each step is held to."""
    if delay == 0:
        return "filtering"
    return "smoothing" if np.isinf(delay) else f"smoothing (a lower bound for a {delay:g} s lag)"


def statistics(exp: Any, cfg: OmniConfig, runs: list[RunSummary], stats: dict) -> None:
    """What the metrics JSON holds beyond the metrics: the settling time, the grid, the units,
    each estimator's bound kind, what reading a real log repaired, the image stage's figures."""
    stats.update({"settle_seconds": cfg.settle, "grid_steps": len(runs[0].t),
                  "units": {"position": "m", "heading": "deg", "map": "m", "seconds": "s"}})
    if runs[0].bounds:
        for name, entry in stats["estimators"].items():
            entry["bound_kind"] = bound_kind(runs[0].delays.get(name, 0.0))
    for name, found in runs[0].survey.items():  # run 0's map against the survey, landmark by landmark
        if name in stats["estimators"]:
            stats["estimators"][name]["survey"] = found
    for name, found in runs[0].unplaced.items():  # run 0's landmarks its data cannot place
        if name in stats["estimators"]:
            stats["estimators"][name]["unplaced"] = found
    if runs[0].repairs:
        stats["data_repairs"] = runs[0].repairs
    if runs[0].images is not None:
        keys = runs[0].images
        stats["images"] = {k: _mean(np.array([r.images[k] for r in runs], float)) for k in keys if k != "bad_frames"}
        stats["images"]["bad_frames"] = runs[0].images["bad_frames"]  # run 0's: (step, reason)
        stats["images"]["units"] = {"bearing_rmse": "deg", "bearing_bias": "deg", "seconds": "s per run"}


def _mean(x: np.ndarray) -> float | None:
    return float(np.nanmean(x)) if np.isfinite(x).any() else None
