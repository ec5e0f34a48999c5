"""Both real NGI pairs (0182/0184 and 0251/0253) in both error modes, the defaults untouched: every
estimator's image II error against the navigation system's (``workbench terrain --scenario ngi
--pair P --mode M --runs 3``, seed 0). Skips without the data."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.experiments.terrain import estimators
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.experiment import EXPERIMENT
from workbench.paths import data_root

run_once = EXPERIMENT.run_once

pytest.importorskip("gtsam")
NGI = data_root() / "ngi"
RUNS = 3
ESTIMATORS = ("navigation", estimators.SEARCH, estimators.REFINED, estimators.ITERATED, estimators.POSTERIOR,
              "gtsam-ba")


@pytest.mark.skipif(not (NGI / "dem.tif").is_file(), reason=f"no ngi data at {NGI} (set WORKBENCH_DATA)")
@pytest.mark.parametrize("mode", ["common", "ii-only"])
@pytest.mark.parametrize("pair", [("0182", "0184"), ("0251", "0253")])
def test_every_estimator_beats_the_navigation_system(pair, mode):
    cfg = TerrainConfig(scenario="ngi", pair=pair, mode=mode, runs=RUNS).validate()
    table = [estimators.TABLE[name] for name in ESTIMATORS]
    pos = {name: [] for name in ESTIMATORS}
    att = {name: [] for name in ESTIMATORS}
    for run in range(RUNS):
        res = run_once(cfg, run, table)
        assert not res.failed, res.failed
        sc = res.scene
        for name, est in res.estimates.items():
            pos[name].append(np.linalg.norm(sc.position[1] - est.position[1]))
            att[name].append(np.linalg.norm(sc.angles[1] - est.angles[1]))
    nav_pos, nav_att = np.mean(pos["navigation"]), np.mean(att["navigation"])
    for name in ESTIMATORS[1:]:
        assert np.mean(pos[name]) < 0.5 * nav_pos, (name, pos[name], pos["navigation"])
        assert np.mean(att[name]) < nav_att, (name, att[name], att["navigation"])
