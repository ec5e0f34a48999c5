"""Configure -> **data -> estimate**: run k's dataset and every estimator on it.

Each run draws its own scene (synthetic: a new terrain, texture and true attitude; ngi: the
same real pair) and its own navigation errors, seeded by ``(seed, run)``; the measured
orientation is the truth moved by those errors. Evaluation is :mod:`.evaluate`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.experiments.contract import Estimator, RunContext, estimate_all
from workbench.experiments.terrain import navigation
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.estimate import Estimate, check
from workbench.experiments.terrain.scenario import Scene, TerrainData, synthetic_scene


@dataclass
class RunResult:
    """One run: its data, every estimate, the search (where it ran), what failed."""

    data: TerrainData
    estimates: dict[str, Estimate]
    estimators: dict[str, Estimator] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)  # estimators that failed: one line each
    search: object | None = None  # search.SearchResult
    record: bool = False          # the recorded run (full-resolution error maps)
    problem: object | None = None  # the search's search.Problem (the bound reads its model)

    @property
    def scene(self) -> Scene:
        return self.data.scene

    @property
    def state(self) -> np.ndarray:
        return self.data.state

    @property
    def measured(self) -> Estimate:
        return self.data.measured

    @property
    def scene_mode(self) -> str:
        return self.data.mode


def make_data(cfg: TerrainConfig, run: int) -> TerrainData:
    """The run's scene, its true navigation errors and the measured orientation."""
    rng = np.random.default_rng([cfg.seed, run])
    if cfg.scenario == "ngi":
        from workbench.experiments.terrain import ngi

        scene = ngi.load(cfg)
    else:
        scene = synthetic_scene(cfg, rng)
    state = navigation.draw_state(cfg, rng)
    pose_err = navigation.error_map(cfg.mode, scene.interval) @ state
    meas = Estimate(*navigation.measured(scene.position, scene.angles, pose_err))
    return TerrainData(scene, meas, state, cfg.mode, rng.bit_generator.state)


def run_once(cfg: TerrainConfig, run: int, estimators: list[Estimator], record: bool = False,
             threads: int = 1) -> RunResult:
    """One run: every estimator on the same measured pair."""
    data = make_data(cfg, run)
    ctx = RunContext(run, record, threads)
    est, failed = estimate_all(estimators, data, cfg, ctx, check)
    found = ctx.get("search")
    return RunResult(data, est, {e.name: e for e in estimators}, failed, found[2] if found else None, record,
                     found[0] if found else None)
