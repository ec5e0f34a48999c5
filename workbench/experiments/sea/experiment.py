"""The sea experiment (paper 002) as the workbench sees it: the one object the CLI, the demo,
the Python API and the sweeps use. The flow goes to this package's role modules
(``run``, ``evaluate``, ``report``, ``record``, ``estimate``, ``estimators``) by name."""

from __future__ import annotations

from workbench.experiments.contract import Demo, Experiment
from workbench.experiments.sea.config import OPTIONS, SCENARIOS, SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData


class Sea(Experiment):
    name = "sea"
    description = ("paper 002: object on the sea from a monocular camera; geometric, diffuse RLS, "
                   "sliding-window RLS, EKF against a GTSAM smoother (LM and iSAM2)")
    config_type = SeaConfig
    scenarios = SCENARIOS
    options = OPTIONS
    data_type = SeaData
    estimate_type = Estimate
    demo = (
        Demo("sea-paper", "paper", estimators="+fixed-lag"),
        Demo("sea-impulse", "impulse", estimators="+fixed-lag"),
        Demo("sea-track-loss", "track-loss", estimators="+fixed-lag"),
        Demo("sea-ais", "ais", max_runs=5, estimators="+fixed-lag"),
    )


EXPERIMENT = Sea()
