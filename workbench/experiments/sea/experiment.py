"""The sea experiment (paper 002) as the workbench sees it: the one object the CLI, the demo,
the Python API and the sweeps use."""

from __future__ import annotations

from workbench.experiments.contract import Demo, Estimator, Experiment
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

    @property
    def estimators(self) -> dict[str, Estimator]:
        from workbench.experiments.sea.estimators import TABLE

        return TABLE

    def run_once(self, cfg: SeaConfig, run: int, estimators: list[Estimator], record: bool = False,
                 threads: int = 1):
        from workbench.experiments.sea.run import run_once

        return run_once(cfg, run, estimators, record)

    def evaluate(self, result, cfg: SeaConfig, run: int):
        from workbench.experiments.sea.evaluate import summarise

        return summarise(result, cfg, run)

    def statistics(self, cfg: SeaConfig, summaries: list, label: str = "") -> dict:
        from workbench.experiments.sea.evaluate import statistics

        return statistics(cfg, summaries, label)

    def table(self, stats: dict) -> str:
        from workbench.experiments.sea.report import table

        return table(stats)

    def blueprint(self, first):
        from workbench.experiments.sea.record import blueprint

        return blueprint(list(first.estimates), images=first.images is not None)

    def record(self, rec, first, summaries: list, table: str) -> None:
        from workbench.experiments.sea.record import record

        record(rec, first, summaries, table)

    def check(self, estimate, data, cfg, estimator: Estimator):
        from workbench.experiments.sea.estimate import check

        return check(estimate, data, cfg, estimator)

    def label(self, first) -> str:
        return first.data.label


EXPERIMENT = Sea()
