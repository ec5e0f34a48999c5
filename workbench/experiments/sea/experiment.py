"""The sea experiment (paper 002) as the workbench sees it: the one object the CLI, the demo,
the Python API and the sweeps use. Its parts (``run``, ``evaluate``, ``report``,
``record``, ``estimate``, ``estimators``) are declared in ``declare()``."""

from __future__ import annotations

from workbench.core import parts
from workbench.core.experiment import Demo, Experiment, Preset
from workbench.core.parts import Later, Parts
from workbench.experiments.sea.config import OPTIONS, SCENARIOS, SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData


def _record():
    """The recording's module (it loads Rerun), imported on first use."""
    from workbench.experiments.sea import record

    return record


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
    presets = (
        Preset("ar-models", "algorithms 2-3's forgetting factor x window x AR order (Fig. 4-5)",
               {"lam": (0.95, 0.98, 1.0), "window": (60, 120, 240), "order": (3, 5, 8)},
               estimators="geometric,rls,window-rls,ekf"),
        Preset("ships", "every AIS ship usable for the run's duration, a cell each (the others named with the "
               "reason)", {"mmsi": ("all",)}, scenario="ais"),
        Preset("noise", "the camera's angle noises, half and twice Table 1's",
               {"sigma_alpha_arcmin": (0.44, 0.88, 1.76), "sigma_beta_arcmin": (0.78, 1.56, 3.12)}),
    )
    headline = ("position_rmse", "rmse_alpha", "anees")
    compared = ("/monte_carlo/position_rmse", "/errors/x", "/errors/y")
    paper_notes = {"rmse_x": "paper's Table 2: geometric 20.7 m, rls 16.9 m (scenario paper)",
                   "rmse_y": "paper's Table 2: geometric 31 m, rls 25.2 m (scenario paper)",
                   "rmse_alpha": "paper's Table 2: geometric 0.88', rls 0.57' (scenario paper)"}

    def declare(self) -> Parts:
        """The sea package's parts."""
        from workbench.experiments.sea import estimate, estimators, evaluate, metrics, report, resample, run

        return parts.declare(
            self.name, make_data=run.make_data, check=estimate.check, estimators=estimators.TABLE,
            metrics=metrics.METRICS, assumed=run.assumed, result_type=run.RunResult, run_once=run.run_once,
            run_count=run.run_count, grid_values=run.grid_values, write_log=run.write_log, tunable=run.tunable,
            resample=resample.resample, bootstrap_nees=metrics.BOOTSTRAP_NEES, summarise=evaluate.summarise,
            statistics=evaluate.statistics, report=report.table, table_columns=metrics.TABLE, bounds=metrics.BOUNDS,
            renamed=metrics.RENAMED, noise_groups=metrics.NOISE_GROUPS, layout=Later(lambda: _record().layout),
            record_run=Later(lambda: _record().record_run), record_runs=Later(lambda: _record().record_runs))


EXPERIMENT = Sea()
