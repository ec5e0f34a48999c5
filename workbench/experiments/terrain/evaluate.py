"""**Evaluate**: a run's errors and summary, and the statistics over runs.

Scored is the orientation of image II (the one the paper corrects); errors are ``truth -
estimate``. The unrefined orientation from the navigation system is the estimator
``navigation``, the reference of every reduction. Each estimate's halftone model is scored
by its ground error over image II (full resolution for the recorded run).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.errors import require
from workbench.estimation import bounds as estimation_bounds
from workbench.estimation import metrics
from workbench.estimation.angles import wrap
from workbench.experiments.terrain import halftone, navigation
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.run import RunResult


def ground_errors(res: RunResult) -> dict[str, np.ndarray]:
    """Per-pixel ground error maps of image II's halftone model per estimate (every pixel for
    the recorded run, about 100 x 100 samples otherwise)."""
    sc = res.scene
    step = 1 if res.record else max(1, min(sc.k.width, sc.k.height) // 100)
    truth = (sc.position[1], sc.angles[1])
    return {name: halftone.ground_error(sc.dem, sc.k, truth, (e.position[1], e.angles[1]), step)
            for name, e in res.estimates.items()}


@dataclass
class RunSummary:
    """What a Monte Carlo worker sends back: small arrays only."""

    run: int
    position: dict[str, np.ndarray]   # (3,) truth - estimate, image II
    attitude: dict[str, np.ndarray]   # (3,) rad
    ground_rmse: dict[str, float]
    seconds: dict[str, float]
    nees: dict[str, float]            # image II's position NEES (3 dof) where the estimator has a covariance
    winner_in_true_cell: bool | None
    winner_in_true_position_cell: bool | None
    hypotheses: int
    nodes: int
    failed: dict[str, str] = field(default_factory=dict)  # estimators that failed: one line each
    ground_maps: dict[str, np.ndarray] = field(default_factory=dict)  # the recorded run's error maps
    bound: dict[str, float] = field(default_factory=dict)  # image II's Cramér-Rao variances (.bounds)
    bound_ba: dict[str, float] = field(default_factory=dict)  # the bundle adjustment's own graph's
    diagnostics: dict[str, dict[str, float]] = field(default_factory=dict)  # DIAGNOSTICS an estimate reports


DIAGNOSTICS = ("kappa", "effective_nodes")
"""Scalars an estimate may carry in its extras and the metrics average over runs: the search's
posterior's variance inflation of the node sum and its effective number of independent nodes
(:mod:`.posterior`)."""


def summarise(res: RunResult, cfg: TerrainConfig, run: int) -> RunSummary:
    """Image II's position and attitude errors, ground RMSE, NEES, whether the search's winner
    is the true cell; the error maps themselves for the recorded run."""
    sc = res.scene
    pos = {n: sc.position[1] - e.position[1] for n, e in res.estimates.items()}
    att = {n: wrap(sc.angles[1] - e.angles[1]) for n, e in res.estimates.items()}
    maps = ground_errors(res)
    rm = {n: halftone.rmse(g) for n, g in maps.items()}
    sec = {n: e.seconds for n, e in res.estimates.items()}
    nees = {}
    for n, e in res.estimates.items():
        cov = e.position_cov
        if cov is not None and np.all(np.isfinite(cov)) and np.linalg.det(cov) > 0:
            nees[n] = float(metrics.nees(pos[n], cov))
    hit = hit_linear = None
    if res.search is not None and res.search.kind == "grid":
        s = res.search
        spacing = np.ptp(s.centres, axis=0) / np.maximum(1, np.array([len(np.unique(c)) - 1 for c in s.centres.T]))
        searched = np.ptp(s.centres, axis=0) > 0
        inside = np.abs(s.centre - res.state) <= 0.5 * spacing + 1e-12
        hit = bool(np.all(inside[searched]))
        linear = np.array([n in navigation.LINEAR for n in navigation.STATE[res.scene_mode]]) & searched
        hit_linear = bool(np.all(inside[linear]))
    diag = {n: {k: float(e.extras[k]) for k in DIAGNOSTICS if k in e.extras} for n, e in res.estimates.items()}
    return RunSummary(run, pos, att, rm, sec, nees, hit, hit_linear,
                      0 if res.search is None else len(res.search.centres),
                      0 if res.search is None else res.search.nodes, dict(res.failed),
                      maps if res.record else {}, cramer_rao(res, cfg), _ba_bound(res, cfg),
                      {n: d for n, d in diag.items() if d})


def _ba_bound(res: RunResult, cfg: TerrainConfig) -> dict[str, float]:
    from workbench.experiments.terrain import bounds

    est = res.estimates.get("gtsam-ba")
    return (bounds.bundle_adjustment(cfg, res.scene, est.extras) if est is not None else None) or {}


def cramer_rao(res: RunResult, cfg: TerrainConfig) -> dict[str, float]:
    """Image II's Cramér-Rao variances for this run (:mod:`.bounds`), from the search's problem
    (made here if no search estimator ran)."""
    from workbench.experiments.terrain import bounds
    from workbench.experiments.terrain import search as rs

    problem = res.problem
    if problem is None:
        sc, meas = res.scene, res.measured
        problem = rs.make_problem(cfg, sc.k, sc.dem, meas.position, meas.angles, sc.images, sc.interval)
    P, r = bounds.state_bound(problem, res.state, cfg)
    return {**bounds.variances(P, cfg, res.scene.interval), "residual_variance": r}


def _bounds(runs: list[RunSummary], pos: np.ndarray, att: np.ndarray, field: str = "bound",
            kind: str = "images and navigation prior") -> dict:
    """Image II's bound (the root of the runs' mean variance bound), the efficiency (the RMS
    error over that) and its Monte Carlo standard error, for position (m) and attitude (mrad)."""
    bound, eff, se = {}, {}, {}
    for q, err, scale in (("position", pos, 1.0), ("attitude", att, 1000.0)):
        sq = np.sum(err**2, axis=1)
        v = np.array([getattr(r, field)[q] for r in runs])
        bound[q] = float(np.sqrt(v.mean())) * scale
        eff[q] = estimation_bounds.efficiency(float(np.sqrt(sq.mean())) * scale, bound[q] ** 2)
        if len(runs) > 1 and sq.mean() > 0:
            se[q] = float(eff[q] * 0.5 * sq.std(ddof=1) / (np.sqrt(len(runs)) * sq.mean()))
    return {"bound": bound, "efficiency": eff, "efficiency_se": se, "bound_kind": kind}


def _paper_fractions(pos: np.ndarray, max_linear: float) -> dict[str, float]:
    """The paper's Fig. 3 quantities: mean and standard deviation of |dX|, |dY| and the radial
    error sqrt(dX^2 + dY^2) over runs, as fractions of the maximum linear error."""
    ax, ay = np.abs(pos[:, 0]) / max_linear, np.abs(pos[:, 1]) / max_linear
    ar = np.hypot(pos[:, 0], pos[:, 1]) / max_linear
    return {"mean_x": float(ax.mean()), "std_x": float(ax.std()), "mean_y": float(ay.mean()),
            "std_y": float(ay.std()), "mean_r": float(ar.mean()), "std_r": float(ar.std())}


def statistics(cfg: TerrainConfig, runs: list[RunSummary], label: str = "") -> dict:
    """The metrics JSON: per estimator, image II's mean position error (m, 3D norm), mean
    attitude error (rad, norm of the three angles), ground RMSE of the halftone model (m, RMS
    over runs), seconds; ``reduction`` is the mean position error over ``navigation``'s; the
    paper's normalised statistics in ``paper``; ``anees`` and ``nees_band`` where there is a
    covariance; the :data:`DIAGNOSTICS` an estimate reports (``kappa``, ``effective_nodes``), means
    over runs."""
    require(len(runs) > 0, "no runs to summarise")
    out: dict = {"experiment": "terrain", "scene": cfg.scenario, "mode": cfg.mode, "seed": cfg.seed,
                 "runs": len(runs), "label": label, "size": cfg.size, "distribution": cfg.distribution,
                 "max_linear": cfg.max_linear, "max_angular": cfg.max_angular, "config": cfg.to_json(),
                 "units": {"position_error": "m", "attitude_error": "rad", "ground_rmse": "m", "seconds": "s"},
                 "hypotheses": runs[0].hypotheses, "nodes": runs[0].nodes, "estimators": {}}
    hits = [r.winner_in_true_cell for r in runs if r.winner_in_true_cell is not None]
    out["winner_in_true_cell"] = float(np.mean(hits)) if hits else None
    hits = [r.winner_in_true_position_cell for r in runs if r.winner_in_true_position_cell is not None]
    out["winner_in_true_position_cell"] = float(np.mean(hits)) if hits else None
    nav_pos = np.mean([np.linalg.norm(r.position["navigation"]) for r in runs])
    nav_att = np.mean([np.linalg.norm(r.attitude["navigation"]) for r in runs])
    nav_ground = np.sqrt(np.mean([r.ground_rmse["navigation"] ** 2 for r in runs]))
    for name in runs[0].position:
        pos = np.stack([r.position[name] for r in runs])
        att = np.stack([r.attitude[name] for r in runs])
        pe = np.linalg.norm(pos, axis=1)
        ae = np.linalg.norm(att, axis=1)
        ground = np.sqrt(np.mean([r.ground_rmse[name] ** 2 for r in runs]))
        out["estimators"][name] = {
            "position_error": float(pe.mean()),
            "position_error_std": float(pe.std()),
            "attitude_error": float(ae.mean()),
            "ground_rmse": float(ground),
            "seconds": float(np.mean([r.seconds[name] for r in runs])),
            "reduction": float(pe.mean() / nav_pos) if nav_pos > 0 else None,
            "attitude_reduction": float(ae.mean() / nav_att) if nav_att > 0 else None,
            "ground_reduction": float(ground / nav_ground) if nav_ground > 0 else None,
            "rmse": {"x": float(np.sqrt(np.mean(pos[:, 0] ** 2))), "y": float(np.sqrt(np.mean(pos[:, 1] ** 2))),
                     "h": float(np.sqrt(np.mean(pos[:, 2] ** 2)))},
            "paper": _paper_fractions(pos, cfg.max_linear),
        }
        if name == "gtsam-ba" and all(r.bound_ba for r in runs):
            out["estimators"][name].update(_bounds(runs, pos, att, "bound_ba", "its tie points and DEM"))
        elif runs[0].bound:
            out["estimators"][name].update(_bounds(runs, pos, att))
        nees = [r.nees[name] for r in runs if name in r.nees]
        if nees:
            lo, hi = metrics.chi2_band(3, len(nees))
            out["estimators"][name]["anees"] = float(np.mean(nees))
            out["estimators"][name]["nees_band"] = [lo, hi]
        for key in DIAGNOSTICS:
            values = [r.diagnostics[name][key] for r in runs if key in r.diagnostics.get(name, {})]
            if values:
                out["estimators"][name][key] = float(np.mean(values))
    return out


RUN_METRICS = {"position_error": "m", "attitude_error": "rad", "ground_rmse": "m", "dx": "m", "dy": "m",
               "dh": "m", "dx_fraction": "of max", "dr_fraction": "of max", "nees": "3 dof", "seconds": "s",
               "position_bound": "m", "position_efficiency": "error / bound"}
"""The per-run figures of a sweep's tidy table, and their units."""


def run_metrics(summary: RunSummary, cfg: TerrainConfig) -> dict[str, dict[str, float]]:
    """One run's figures per estimator (a sweep's rows): image II's position error (3D norm)
    and its components (truth - estimate), the attitude error (norm), the halftone model's
    ground RMSE, the paper's Fig. 3 quantities ``|dX| / max`` and ``sqrt(dX^2 + dY^2) / max`` (their
    means and spreads over runs are the paper's), the position NEES where there is a covariance,
    the seconds; the position's Cramér-Rao bound and the error over it."""
    out = {}
    for name, p in summary.position.items():
        entry = {"position_error": float(np.linalg.norm(p)), "attitude_error": float(np.linalg.norm(
                 summary.attitude[name])), "ground_rmse": float(summary.ground_rmse[name]), "dx": float(p[0]),
                 "dy": float(p[1]), "dh": float(p[2]), "dx_fraction": float(abs(p[0]) / cfg.max_linear),
                 "dr_fraction": float(np.hypot(p[0], p[1]) / cfg.max_linear), "seconds": float(summary.seconds[name])}
        if name in summary.nees:
            entry["nees"] = float(summary.nees[name])
        if summary.bound:
            entry["position_bound"] = float(np.sqrt(summary.bound["position"]))
            entry["position_efficiency"] = estimation_bounds.efficiency(entry["position_error"],
                                                                        summary.bound["position"])
        out[name] = entry
    return out
