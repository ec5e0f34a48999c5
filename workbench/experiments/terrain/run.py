"""Configure -> **data -> estimate**: run k's dataset and every estimator on it.

Each run draws its own scene (synthetic: a new terrain, texture and true attitude; ngi: the
same real pair) and its own navigation errors, seeded by ``(seed, run)``; the measured
orientation is the truth moved by those errors. Evaluation is :mod:`.evaluate`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core import experiment as contract
from workbench.experiments.terrain import navigation
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.scenario import Scene, TerrainData, synthetic_scene


@dataclass
class RunResult(contract.RunResult):
    """One run (:class:`~workbench.core.experiment.RunResult`): its data, every estimate, the
    search (where it ran), what failed; ``record``: the recorded run (full-resolution error maps)."""

    @property
    def search(self):
        """The search's result (search.SearchResult), where a search estimator ran."""
        found = self.products.get("search")
        return found[2] if found else None

    @property
    def problem(self):
        """The search's search.Problem (the bound reads its model), where a search estimator ran."""
        found = self.products.get("search")
        return found[0] if found else None

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
    """The run's scene, its true navigation errors and the measured orientation (a log: as it
    gives them). The sampled hypotheses draw from their own stream, seeded by ``(seed, run, 1)``,
    so a run written out and read back (:mod:`.log`) draws the same ones."""
    if cfg.scenario == "log":
        from workbench.experiments.terrain.readers import log

        return log.read(cfg.data, cfg, run)
    rng = np.random.default_rng([cfg.seed, run])
    if cfg.scenario == "ngi":
        from workbench.experiments.terrain.readers import ngi

        scene = ngi.load(cfg)
    else:
        scene = synthetic_scene(cfg, rng)
    state = navigation.draw_state(cfg, rng)
    pose_err = navigation.error_map(cfg.mode, scene.interval) @ state
    meas = Estimate(*navigation.measured(scene.position, scene.angles, pose_err))
    return TerrainData(scene, meas, state, cfg.mode, np.random.default_rng([cfg.seed, run, 1]).bit_generator.state)


def write_log(data: TerrainData, folder, force: bool = False) -> list:
    """A dataset in the open log format (``--export-data``; :mod:`.log`)."""
    from workbench.experiments.terrain.readers import log

    return log.write(data, folder, force)
