"""Configure -> **data -> estimate**: run k's dataset and every estimator on it.

A dataset is made (simulated, or a real AIS ship's track) and seeded by ``(seed, run)``; with
``from_images`` the frames are rendered and the angles detected from them, and the estimators
run once more on the simulated angles of the same run for comparison. Evaluation is
:mod:`.evaluate`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.experiments.contract import Estimator, RunContext, estimate_all
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate, check
from workbench.experiments.sea.scenario import SeaData, simulate


@dataclass
class RunResult:
    """One run: its data and every estimate (and what failed)."""

    data: SeaData
    estimates: dict[str, Estimate]
    estimators: dict[str, Estimator] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)  # estimators that failed: one line each
    images: object | None = None                  # the image stage (``from_images``): images.ImageStage
    simulated: tuple[SeaData, dict[str, Estimate]] | None = None  # the same run on simulated angles
    scenario_seen: np.ndarray | None = None       # the scenario's own seen mask


def make_data(cfg: SeaConfig, run: int) -> SeaData:
    """The run's dataset, seeded by ``(seed, run)`` so runs are independent and repeatable."""
    rng = np.random.default_rng([cfg.seed, run])
    if cfg.scenario == "ais":
        from workbench.experiments.sea import ais

        ship = ais.ship_scenario(cfg.data, cfg.mmsi, cfg.duration, cfg.dt, cfg.ais_range)
        return simulate(cfg, rng, target=ship["target"], observer=ship["observer"],
                        course=ship["course"], label=ship["label"])
    return simulate(cfg, rng)


def run_once(cfg: SeaConfig, run: int, estimators: list[Estimator], record: bool = False,
             threads: int = 1) -> RunResult:
    """One run: every estimator on the same data, each estimate checked (:func:`.estimate.check`).
    ``record``: the recorded run (covariances from the smoothers, the frames kept)."""
    data = make_data(cfg, run)
    table = {e.name: e for e in estimators}
    if not cfg.from_images:
        est, failed = estimate_all(estimators, data, cfg, RunContext(run, record), check)
        return RunResult(data, est, table, failed)
    from workbench.experiments.sea import images

    stage = images.measure(data, cfg, run, record)
    img = images.from_stage(data, stage)
    est, failed = estimate_all(estimators, img, cfg, RunContext(run, record), check)
    sim, failed_sim = estimate_all(estimators, data, cfg, RunContext(run, False), check)
    return RunResult(img, est, table, {**failed_sim, **failed}, stage, (data, sim), data.seen)
