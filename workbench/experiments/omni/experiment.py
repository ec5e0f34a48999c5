"""The omni experiment (paper 000) as the workbench sees it: the one object the CLI, the demo,
the Python API and the sweeps use."""

from __future__ import annotations

from pathlib import Path

from workbench.experiments.contract import Demo, Estimator, Experiment
from workbench.experiments.omni.config import EXTRAS, OPTIONS, SCENARIOS, OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData


class Omni(Experiment):
    name = "omni"
    description = ("paper 000: odometer + hemispherical camera; bearing-only EKF-SLAM (UT-gated landmark "
                   "initialisation) against GTSAM iSAM2 and batch LM; simulation and the MRCLAM robots")
    config_type = OmniConfig
    scenarios = SCENARIOS
    options = OPTIONS
    extras = EXTRAS
    data_type = OmniData
    estimate_type = SlamEstimate
    demo = (  # 500 s of SLAM per run with every estimator: about 12 s a run
        Demo("omni-paper", "paper", max_runs=4, estimators="+fixed-lag"),
        Demo("omni-mrclam1", "mrclam", {"robot": 1}, max_runs=1),
        Demo("omni-mrclam2", "mrclam", {"robot": 2}, max_runs=1),
    )

    @property
    def estimators(self) -> dict[str, Estimator]:
        from workbench.experiments.omni.estimators import TABLE

        return TABLE

    def run_once(self, cfg: OmniConfig, run: int, estimators: list[Estimator], record: bool = False,
                 threads: int = 1):
        from workbench.experiments.omni.run import run_once

        return run_once(cfg, run, estimators, record)

    def evaluate(self, result, cfg: OmniConfig, run: int):
        from workbench.experiments.omni.evaluate import summarise

        return summarise(result, run)

    def statistics(self, cfg: OmniConfig, summaries: list, label: str = "") -> dict:
        from workbench.experiments.omni.evaluate import statistics

        return statistics(cfg, summaries, label)

    def table(self, stats: dict) -> str:
        from workbench.experiments.omni.report import table

        return table(stats)

    def blueprint(self, first):
        """Maps framed on the walls (the simulation) or the landmarks (MRCLAM)."""
        import numpy as np

        from workbench.experiments.omni.record import blueprint

        d = first.data
        if d.walls is not None:
            centre, height = tuple(d.walls.mean(axis=0)), 1.4 * float(d.walls.max() - d.walls.min())
        else:
            lo, hi = np.nanmin(d.landmarks, axis=0), np.nanmax(d.landmarks, axis=0)
            centre, height = tuple((lo + hi) / 2), 1.6 * float(max(hi - lo))
        return blueprint(list(first.estimates), centre, height, first.images is not None)

    def record(self, rec, first, summaries: list, table: str) -> None:
        from workbench.experiments.omni.record import record

        record(rec, first, summaries, table)

    def check(self, estimate, data, cfg, estimator: Estimator):
        from workbench.experiments.omni.estimate import check

        return check(estimate, data, cfg, estimator)

    def label(self, first) -> str:
        return first.data.label

    def check_extras(self, cfg: OmniConfig, extras: dict, force: bool) -> None:
        from workbench.recording import stream

        if extras.get("export_tum") is not None:
            for name in ("truth", *cfg.estimators):
                stream.check_plain_output(Path(extras["export_tum"]) / f"{name.split('=')[0]}.tum", force,
                                          "TUM trajectory")

    def export(self, first, stats: dict, extras: dict, force: bool) -> list[str]:
        """``export_tum``: run 0's trajectories (truth and every estimator) as TUM files, for evo."""
        folder = extras.get("export_tum")
        if folder is None:
            return []
        from workbench.experiments.omni import tum

        d = first.data
        trajectories = {"truth": (d.t, d.truth)}
        trajectories.update({name: (d.t[est.steps], est.pose) for name, est in first.estimates.items()})
        stats["tum"] = [str(p) for p in tum.export(folder, trajectories, force)]
        return [f"TUM:       {folder}/"]


EXPERIMENT = Omni()
