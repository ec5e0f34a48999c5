"""**Evaluate**: a run's errors on its grid and its summary, and the statistics over runs.

Every estimator is scored on one grid of steps: the graph's keyframes (every bearing epoch,
and at least one per ``keyframe_every`` seconds), where all of them have an estimate.
Errors are ``truth - estimate`` with the heading wrapped; "after settling" means from
``settle`` seconds on (the paper's claims are for the settled filter, after the first loop).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from workbench.errors import require
from workbench.estimation import bounds, metrics
from workbench.estimation.alignment import umeyama
from workbench.estimation.angles import wrap
from workbench.experiments.omni import bounds as omni_bounds
from workbench.experiments.omni import graph
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.run import RunResult


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
    """NEES of the pose (3 dof) per row; NaN where either is unknown or the covariance singular."""
    out = np.full(len(err), np.nan)
    ok = np.isfinite(err).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    if ok.any():
        c = cov[ok]
        good = np.linalg.det(c) > 0
        idx = np.flatnonzero(ok)[good]
        out[idx] = metrics.nees(err[idx], cov[idx])
    return out


@dataclass
class RunSummary:
    """What a Monte Carlo worker sends back: small arrays only."""

    run: int
    t: np.ndarray
    errors: dict[str, np.ndarray]
    sigmas: dict[str, np.ndarray]
    nees: dict[str, np.ndarray]
    map_errors: dict[str, np.ndarray]
    init_delay: dict[str, np.ndarray]
    seconds: dict[str, float]
    failures: dict[str, int]
    images: dict | None = None
    failed: dict[str, str] = field(default_factory=dict)  # estimators that failed: one line each
    delays: dict[str, float] = field(default_factory=dict)  # each estimator's delay (its bound)
    aligned: dict[str, np.ndarray] = field(default_factory=dict)  # errors after the best rigid alignment
    alignment: dict[str, tuple[float, float, float]] = field(default_factory=dict)  # its rotation, translation
    gated: dict[str, int] = field(default_factory=dict)  # bearings each estimator's gate left out
    smoothed: dict[str, np.ndarray] = field(default_factory=dict)  # a smoother's errors at the end (G, 3)
    repairs: dict = field(default_factory=dict)  # what the real data needed to be read (omni.real)
    bounds: dict = field(default_factory=dict)  # delay -> {position, heading} (G,) variances; "map" (N,)


def summarise(result: RunResult, cfg: OmniConfig, run: int) -> RunSummary:
    """Errors, own sigmas and NEES on the grid; the final map's errors; initialisation delays."""
    data, grid = result.data, result.grid
    truth = data.truth[grid]
    errs, sig, nees, maps, delay = {}, {}, {}, {}, {}
    for name, est in result.estimates.items():
        pose, cov = on_grid(est, grid)
        e = pose_errors(truth, pose)
        errs[name] = e
        sig[name] = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
        nees[name] = pose_nees(e, cov)
        maps[name] = est.final_map - data.landmarks
        d = np.full(len(data.landmarks), np.nan)
        ok = est.init_step >= 0
        d[ok] = data.t[est.init_step[ok]] - data.t[est.first_seen[ok]]
        delay[name] = d
    aligned, alignment = {}, {}
    for name, est in result.estimates.items():
        pose, _ = on_grid(est, grid)
        a = umeyama(pose[:, :2], truth[:, :2])
        aligned[name] = pose_errors(truth, a.apply(pose))
        alignment[name] = (a.rotation, float(a.translation[0]), float(a.translation[1]))
    smoothed = {name: pose_errors(truth, smoothed_on_grid(est, grid))
                for name, est in result.estimates.items() if est.smoothed is not None}
    delays = {n: result.estimators[n].delay for n in result.estimates if n in result.estimators}
    crb = {}
    if result.images is None:  # bearings from images have the image stage's noise, not the model's: no bound
        kf = result.keyframes if result.keyframes is not None else graph.keyframes(data, cfg)
        crb = omni_bounds.variances(data, kf, {0.0, float("inf")} | {0.0 if d == 0 else float("inf")
                                                                    for d in delays.values()})
    return RunSummary(run, data.t[grid], errs, sig, nees, maps, delay,
                      {n: e.seconds for n, e in result.estimates.items()},
                      {n: e.failures for n, e in result.estimates.items()},
                      result.images.stats if result.images is not None else None, dict(result.failed),
                      delays, aligned=aligned, alignment=alignment, bounds=crb, repairs=dict(data.repairs or {}),
                      gated={n: e.gated for n, e in result.estimates.items()}, smoothed=smoothed)


def bound_kind(delay: float) -> str:
    """The bound an estimator using ``delay`` s of data after each step is held to."""
    if delay == 0:
        return "filtering"
    return "smoothing" if np.isinf(delay) else f"smoothing (a lower bound for a {delay:g} s lag)"


def _bound_summary(runs: list[RunSummary], name: str, E: np.ndarray, M: np.ndarray, settled: np.ndarray
                   ) -> tuple[dict, dict, dict, str] | None:
    """An estimator's bounds (the root of the variance bound averaged over the runs and the settled
    steps it estimates; the map's over the landmarks it has), efficiencies (its RMSE over the same
    over that) and their Monte Carlo standard errors."""
    if not runs[0].bounds:
        return None
    delay = runs[0].delays.get(name, 0.0)
    key = 0.0 if delay == 0 else float("inf")
    V = {q: np.stack([r.bounds[key][q] for r in runs]) for q in ("position", "heading")}
    sq = {"position": E[..., 0] ** 2 + E[..., 1] ** 2, "heading": E[..., 2] ** 2}
    bound, eff, se = {}, {}, {}
    for q, scale in (("position", 1.0), ("heading", math.degrees(1.0))):
        ok = np.isfinite(sq[q]) & settled[None, :]
        if not ok.any():
            continue
        b = float(np.sqrt(np.mean(V[q][ok]))) * scale
        per_run = np.array([sq[q][i][ok[i]].mean() for i in range(len(runs)) if ok[i].any()])
        bound[q] = b
        eff[q] = bounds.efficiency(float(np.sqrt(sq[q][ok].mean())) * scale, b**2)
        if len(per_run) > 1:
            se[q] = float(eff[q] * 0.5 * per_run.std(ddof=1) / (np.sqrt(len(per_run)) * per_run.mean()))
    maps = np.concatenate([r.bounds["map"] for r in runs])
    ok = np.isfinite(M).all(axis=1) & np.isfinite(maps)
    if ok.any():
        bound["map"] = float(np.sqrt(np.mean(maps[ok])))
        eff["map"] = bounds.efficiency(float(np.sqrt(np.mean(np.sum(M[ok] ** 2, axis=1)))), bound["map"] ** 2)
    return bound, eff, se, bound_kind(delay)


def statistics(cfg: OmniConfig, runs: list[RunSummary], label: str = "") -> dict:
    """The metrics JSON: per estimator, errors after settling (and over the whole run), the
    map, landmark initialisation delays, the filter's own sigmas and the pose NEES."""
    require(len(runs) > 0, "no runs to summarise")
    t = runs[0].t
    settled = t >= cfg.settle
    if not settled.any():
        settled = np.ones_like(settled)
    lo, hi = metrics.chi2_band(3, len(runs))
    out: dict = {"experiment": "omni", "scenario": cfg.scenario, "seed": cfg.seed, "runs": len(runs),
                 "label": label, "settle_seconds": cfg.settle, "grid_steps": len(t), "config": cfg.to_json(),
                 "units": {"position": "m", "heading": "deg", "map": "m", "seconds": "s"},
                 "nees_band": [lo, hi], "estimators": {}}
    for name in runs[0].errors:
        E = np.stack([r.errors[name] for r in runs])            # (R, G, 3)
        S = np.stack([r.sigmas[name] for r in runs])
        N = np.stack([r.nees[name] for r in runs])
        # landmarks per run differ with image tracks: pool them
        M = np.concatenate([r.map_errors[name] for r in runs])   # (sum N, 2)
        D = np.concatenate([r.init_delay[name] for r in runs])
        pos = np.hypot(E[..., 0], E[..., 1])
        head = np.degrees(np.abs(E[..., 2]))
        after = settled[None, :]
        map_err = np.hypot(M[..., 0], M[..., 1])
        nees_mean = _nanmean0(N)
        entry = {
            "rmse": {"position": _rms(pos[:, settled]), "heading": _rms(head[:, settled]),
                     "map": _rms(map_err)},
            "rmse_whole_run": {"position": _rms(pos), "heading": _rms(head)},
            "max": {"position": _max(pos[:, settled]), "heading": _max(head[:, settled])},
            "max_whole_run": {"position": _max(pos), "heading": _max(head)},
            "final": {"position": _rms(pos[:, -1:])},
            "sigma": {"position_max": _max(np.hypot(S[..., 0], S[..., 1])[:, settled]),
                      "x_max": _max(S[..., 0][:, settled]), "y_max": _max(S[..., 1][:, settled]),
                      "heading_max": _max(np.degrees(S[..., 2])[:, settled])},
            "anees": _mean(N[:, settled] if after.any() else N),
            "nees_inside_band": float(np.nanmean((nees_mean[settled] >= lo) & (nees_mean[settled] <= hi)))
            if np.isfinite(nees_mean[settled]).any() else None,
            "landmarks_initialised": float(np.mean([np.isfinite(r.map_errors[name][:, 0]).sum() for r in runs])),
            "init_seconds": {"mean": _mean(D), "median": float(np.nanmedian(D)) if np.isfinite(D).any() else None,
                             "max": _max(D)},
            "coverage": float(np.mean(np.isfinite(pos))),
            "failures": int(sum(r.failures[name] for r in runs)),
            "bearings_gated": int(sum(r.gated.get(name, 0) for r in runs)),
            "seconds": float(np.mean([r.seconds[name] for r in runs])),
        }
        A = np.stack([r.aligned[name] for r in runs])
        apos, ahead = np.hypot(A[..., 0], A[..., 1]), np.degrees(np.abs(A[..., 2]))
        rot = np.array([r.alignment[name] for r in runs])
        entry["rmse_aligned"] = {"position": _rms(apos[:, settled]), "heading": _rms(ahead[:, settled])}
        entry["rmse_aligned_whole_run"] = {"position": _rms(apos), "heading": _rms(ahead)}
        entry["alignment"] = {"rotation_deg": _rms(np.degrees(rot[:, 0])),
                              "translation": _rms(np.hypot(rot[:, 1], rot[:, 2]))}
        if all(name in r.smoothed for r in runs):
            F = np.stack([r.smoothed[name] for r in runs])
            fpos, fhead = np.hypot(F[..., 0], F[..., 1]), np.degrees(np.abs(F[..., 2]))
            entry["rmse_smoothed"] = {"position": _rms(fpos[:, settled]), "heading": _rms(fhead[:, settled])}
            entry["rmse_smoothed_whole_run"] = {"position": _rms(fpos), "heading": _rms(fhead)}
        crb = _bound_summary(runs, name, E, M, settled)
        if crb is not None:
            entry["bound"], entry["efficiency"], entry["efficiency_se"], entry["bound_kind"] = crb
        out["estimators"][name] = entry
    if runs[0].repairs:
        out["data_repairs"] = runs[0].repairs
    if runs[0].images is not None:
        keys = runs[0].images
        out["images"] = {k: _mean(np.array([r.images[k] for r in runs], float)) for k in keys if k != "bad_frames"}
        out["images"]["bad_frames"] = runs[0].images["bad_frames"]  # run 0's: (step, reason)
        out["images"]["units"] = {"bearing_rmse": "deg", "bearing_bias": "deg", "seconds": "s per run"}
    return out


def _nanmean0(x: np.ndarray) -> np.ndarray:
    """Mean over runs per step; NaN (without a warning) where no run has a value."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(x, axis=0)


def _rms(x: np.ndarray) -> float | None:
    return float(np.sqrt(np.nanmean(np.square(x)))) if np.isfinite(x).any() else None


def _max(x: np.ndarray) -> float | None:
    return float(np.nanmax(x)) if np.isfinite(x).any() else None


def _mean(x: np.ndarray) -> float | None:
    return float(np.nanmean(x)) if np.isfinite(x).any() else None


def mc_curves(runs: list[RunSummary]) -> dict[str, dict[str, np.ndarray]]:
    """Per estimator, over runs: RMS position error, RMS heading error (deg), mean NEES per step."""
    out = {}
    for name in runs[0].errors:
        E = np.stack([r.errors[name] for r in runs])
        N = np.stack([r.nees[name] for r in runs])
        with np.errstate(all="ignore"):
            out[name] = {
                "position": np.sqrt(_nanmean0(E[..., 0] ** 2 + E[..., 1] ** 2)),
                "heading": np.degrees(np.sqrt(_nanmean0(E[..., 2] ** 2))),
                "nees": _nanmean0(N),
            }
    return out


RUN_METRICS = {"position_rmse": "m", "heading_rmse": "deg", "map_rmse": "m", "final_position": "m",
               "anees": "3 dof", "landmarks": "count", "seconds": "s", "position_bound": "m",
               "position_efficiency": "RMSE / bound"}
"""The per-run figures of a sweep's tidy table, and their units."""


def run_metrics(summary: RunSummary, cfg: OmniConfig) -> dict[str, dict[str, float]]:
    """One run's figures per estimator (a sweep's rows): position and heading RMSE after
    settling, the final map's RMSE, the last pose's error, the mean NEES after settling, the
    landmarks initialised, the seconds; the position's Cramér-Rao bound from this run and the
    efficiency against it. NaN where an estimator has none (odometry's map)."""
    settled = summary.t >= cfg.settle
    if not settled.any():
        settled = np.ones_like(settled)
    out = {}
    for name, E in summary.errors.items():
        pos = np.hypot(E[:, 0], E[:, 1])
        m = summary.map_errors[name]
        entry = {"position_rmse": _rms(pos[settled]), "heading_rmse": _rms(np.degrees(E[settled, 2])),
                 "map_rmse": _rms(np.hypot(m[:, 0], m[:, 1])), "final_position": _rms(pos[-1:]),
                 "anees": _mean(summary.nees[name][settled]), "landmarks": float(np.isfinite(m[:, 0]).sum()),
                 "seconds": float(summary.seconds[name])}
        if summary.bounds:
            key = 0.0 if summary.delays.get(name, 0.0) == 0 else float("inf")
            bound = float(np.sqrt(np.mean(summary.bounds[key]["position"][settled])))
            entry["position_bound"] = bound
            entry["position_efficiency"] = bounds.efficiency(entry["position_rmse"] or np.nan, bound**2)
        out[name] = {k: (np.nan if v is None else float(v)) for k, v in entry.items()}
    return out
