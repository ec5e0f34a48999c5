"""The omni experiment (paper 000) as the workbench sees it: the one object the CLI, the demo,
the Python API and the sweeps use. Its parts are declared in ``declare()``;
here are its declarations and the TUM export (``--export-tum``)."""

from __future__ import annotations

from pathlib import Path

from workbench.core import parts
from workbench.core.experiment import Demo, Experiment, Preset
from workbench.core.parts import Later, Parts
from workbench.errors import require
from workbench.experiments.omni.config import EXTRAS, OPTIONS, SCENARIOS, OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData


def _record():
    """The recording's module (it loads Rerun), imported on first use."""
    from workbench.experiments.omni import record

    return record


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
        # robot 3 misreads four barcodes at 255 s: the gated bearings drawn red in each map
        Demo("omni-mrclam3", "mrclam", {"robot": 3}, max_runs=1),
    )
    presets = (
        Preset("initialisation", "the skewness gate x the bearing noise x the bearing rate (the UT-gated "
               "initialisation (1)-(5))", {"skew_gate": (0.1, 0.3, 1.0), "sigma_bearing_deg": (0.5, 1.0, 2.0),
                                          "bearing_rate": (2.0, 5.0, 10.0)}, estimators="odometry,ekf,isam2"),
    )
    headline = ("position_rmse", "heading_rmse", "anees")
    compared = ("/monte_carlo/position", "/monte_carlo/heading", "/errors/position", "/errors/heading")
    paper_notes = {"position_rmse": "paper's claim: under 0.5 m after settling (scenario paper)",
                   "heading_rmse": "paper's claim: under 1 deg after settling (scenario paper)"}

    def declare(self) -> Parts:
        """The omni package's parts."""
        from workbench.experiments.omni import estimate, estimators, evaluate, metrics, report, resample, run

        return parts.declare(
            self.name, make_data=run.make_data, check=estimate.check, estimators=estimators.TABLE,
            metrics=metrics.METRICS, assumed=run.assumed, result_type=run.RunResult, run_once=run.run_once,
            write_log=run.write_log, tunable=run.tunable, components=run.components, hold_rows=run.hold_rows,
            resample=resample.resample,
            bootstrap_nees=metrics.BOOTSTRAP_NEES, summarise=evaluate.summarise,
            statistics=evaluate.statistics, report=report.table, table_columns=metrics.TABLE,
            bounds=metrics.BOUNDS, renamed=metrics.RENAMED, noise_groups=metrics.NOISE_GROUPS,
            layout=Later(lambda: _record().layout), record_run=Later(lambda: _record().record_run),
            record_runs=Later(lambda: _record().record_runs))

    def check_extras(self, cfg: OmniConfig, extras: dict, force: bool) -> None:
        from workbench.recording import stream

        super().check_extras(cfg, extras, force)
        if extras.get("export_tum") is not None:
            folder = str(extras["export_tum"])
            require(folder.strip() != "", "--export-tum needs a folder name, got ''")
            require(not Path(folder).exists() or Path(folder).is_dir(), f"--export-tum {folder}: not a folder")
            for name in ("truth", *cfg.estimators):
                stream.check_plain_output(Path(extras["export_tum"]) / f"{name.split('=')[0]}.tum", force,
                                          "TUM trajectory")

    def export(self, first, stats: dict, extras: dict, force: bool) -> list[str]:
        """``export_tum``: run 0's trajectories (truth and every estimator) as TUM files, for evo."""
        folder = extras.get("export_tum")
        lines = super().export(first, stats, extras, force)
        if folder is None:
            return lines
        from workbench.experiments.omni.readers import tum

        d = first.data
        trajectories = {"truth": (d.t, d.truth)}
        trajectories.update({name: (d.t[est.steps], est.pose) for name, est in first.estimates.items()})
        stats["tum"] = [str(p) for p in tum.export(folder, trajectories, force)]
        return [*lines, f"TUM:       {folder}/"]


EXPERIMENT = Omni()
