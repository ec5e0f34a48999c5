"""**Evaluate**: a run's summary beside its metrics (:mod:`.metrics`), and what the metrics JSON
holds beyond them.

Scored is the orientation of image II (the one the paper corrects); errors are ``truth -
estimate``. The unrefined orientation from the navigation system is the estimator
``navigation``, the reference of every reduction. Each estimate's halftone model is scored
by its ground error over image II (full resolution for the recorded run).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from workbench.core.experiment import RunSummary as Summary
from workbench.estimation.angles import wrap
from workbench.experiments.terrain import navigation
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.metrics import ba_bound, ground_maps
from workbench.experiments.terrain.run import RunResult
from workbench.metrics import base as metric


@dataclass
class RunSummary(Summary):
    """What a Monte Carlo worker sends back beside the metrics: small arrays only."""

    position: dict[str, np.ndarray]   # (3,) truth - estimate, image II
    attitude: dict[str, np.ndarray]   # (3,) rad
    winner_in_true_cell: bool | None
    winner_in_true_position_cell: bool | None
    hypotheses: int
    nodes: int
    ground_maps: dict[str, np.ndarray] = field(default_factory=dict)  # the recorded run's error maps
    ba_bound: bool = False            # the bundle adjustment's own graph gave its bound (else the images')
    repairs: dict = field(default_factory=dict)  # what reading the real files needed (ngi, log): data_repairs


def summarise(res: RunResult, cfg: TerrainConfig, run: int) -> RunSummary:
    """Image II's position and attitude errors, whether the search's winner is the true cell;
    the ground error maps themselves for the recorded run (:func:`.metrics.ground_maps`)."""
    sc = res.scene
    pos = {n: sc.position[1] - e.position[1] for n, e in res.estimates.items()}
    att = {n: wrap(sc.angles[1] - e.angles[1]) for n, e in res.estimates.items()}
    hit = hit_linear = None
    if res.search is not None and res.search.kind == "grid" and np.isfinite(res.state).all():  # (a log: no truth)
        s = res.search
        spacing = np.ptp(s.centres, axis=0) / np.maximum(1, np.array([len(np.unique(c)) - 1 for c in s.centres.T]))
        searched = np.ptp(s.centres, axis=0) > 0
        inside = np.abs(s.centre - res.state) <= 0.5 * spacing + 1e-12
        hit = bool(np.all(inside[searched]))
        linear = np.array([n in navigation.LINEAR for n in navigation.STATE[res.scene_mode]]) & searched
        hit_linear = bool(np.all(inside[linear]))
    maps = ground_maps(metric.MetricContext(cfg, run, cache=res.cache, result=res)) if res.record else {}
    has_ba = "gtsam-ba" in res.estimates and bool(res.shared("bound_ba", lambda: ba_bound(res, cfg)))
    return RunSummary(run, pos, att, hit, hit_linear, 0 if res.search is None else len(res.search.centres),
                      0 if res.search is None else res.search.nodes, maps, has_ba,
                      dict(sc.extras.get("repairs") or {}), failed=dict(res.failed))


def statistics(exp: Any, cfg: TerrainConfig, runs: list[RunSummary], stats: dict) -> None:
    """What the metrics JSON holds beyond the metrics: the error mode and its sizes, the units,
    the search's hypotheses and nodes and how often its winner is the true cell, each estimator's
    bound, and its position, attitude and ground errors over the navigation system's (``reduction``,
    ``attitude_reduction``, ``ground_reduction``); what reading the real files repaired
    (``data_repairs``)."""
    stats.update({"mode": cfg.mode, "size": cfg.size, "distribution": cfg.distribution,
                  "max_linear": cfg.max_linear, "max_angular": cfg.max_angular,
                  "units": {"position_error": "m", "attitude_error": "rad", "ground_rmse": "m", "seconds": "s"},
                  "hypotheses": runs[0].hypotheses, "nodes": runs[0].nodes})
    if runs[0].repairs:
        stats["data_repairs"] = dict(runs[0].repairs)
    hits = [r.winner_in_true_cell for r in runs if r.winner_in_true_cell is not None]
    stats["winner_in_true_cell"] = float(np.mean(hits)) if hits else None
    hits = [r.winner_in_true_position_cell for r in runs if r.winner_in_true_position_cell is not None]
    stats["winner_in_true_position_cell"] = float(np.mean(hits)) if hits else None
    nav = stats["estimators"]["navigation"]
    for name, e in stats["estimators"].items():
        for key, figure in (("reduction", "position_error"), ("attitude_reduction", "attitude_error"),
                            ("ground_reduction", "ground_rmse")):
            e[key] = e[figure] / nav[figure] if nav.get(figure) else None
        if "position_bound" in e:
            own = name == "gtsam-ba" and all(r.ba_bound for r in runs)
            e["bound_kind"] = "its tie points and DEM" if own else "images and navigation prior"
