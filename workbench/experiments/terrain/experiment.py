"""The terrain experiment (paper 001) as the workbench sees it: the one object the CLI, the
demo, the Python API and the sweeps use. Its parts are declared in
``declare()``; here are its declarations (the paper's grid is the sweep preset ``paper-grid``) and the halftone
model's export (``--model``, :mod:`.model`)."""

from __future__ import annotations

from pathlib import Path

from workbench.core import parts
from workbench.core.experiment import Command, Demo, Experiment, Preset
from workbench.core.parts import Later, Parts
from workbench.errors import require
from workbench.experiments.terrain import grid
from workbench.experiments.terrain.config import EXTRAS, OPTIONS, SCENARIOS, TerrainConfig
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.scenario import TerrainData


def _measure(which: str):
    """``measure``'s command line or Python function, imported when first used."""
    from workbench.experiments.terrain.products import command as commands

    return getattr(commands, which)


def _record():
    """The recording's module (it loads Rerun), imported on first use."""
    from workbench.experiments.terrain import record

    return record


class Terrain(Experiment):
    name = "terrain"
    description = ("paper 001: aerial stereo pair + DEM; recurrent-search estimation (a Kalman filter bank "
                   "over error hypotheses) against GTSAM bundle adjustment; synthetic and the real NGI frames")
    config_type = TerrainConfig
    scenarios = SCENARIOS
    options = OPTIONS
    extras = EXTRAS
    required = ("navigation",)
    data_type = TerrainData
    estimate_type = Estimate
    demo = (  # about 9 s a run
        Demo("terrain-common", "synthetic", {"mode": "common"}, max_runs=4),
        Demo("terrain-ii-only", "synthetic", {"mode": "ii-only"}, max_runs=4),
        Demo("terrain-ngi", "ngi", {"mode": "ii-only"}, max_runs=1),
    )
    presets = (
        Preset("paper-grid", "the paper's grid (Fig. 3): image sizes x maximum linear and angular errors x the "
               "number of functionals, hypotheses drawn in the confidence cube",
               {"size": grid.SIZES, "max_linear": grid.LINEAR, "max_angular": grid.ANGULAR,
                "samples": grid.FUNCTIONALS},
               overrides={"hypotheses": "sample"}, estimators="navigation,recurrent-search,recurrent-search-refined",
               report=grid.from_sweep),
    )
    commands = (Command("measure", lambda: _measure("measure_command"), lambda: _measure("measure")),)
    headline = ("dr_fraction", "dx_fraction", "position_error")
    compared = ()
    paper_notes = {"dr_fraction": "paper (Fig. 3): mean radial error 40-60 % of the maximum after processing; "
                   "its spread 3-10 % (100x100), 2-8 % (200x200)",
                   "dx_fraction": "paper (Fig. 3): mean |dX| at most 40-60 % of the maximum; spread 6-16 % "
                   "(100x100), 4-13 % (200x200)"}

    def declare(self) -> Parts:
        """The terrain package's parts."""
        from workbench.experiments.terrain import estimate, estimators, evaluate, metrics, report, run

        return parts.declare(
            self.name, make_data=run.make_data, check=estimate.check, estimators=estimators.TABLE,
            metrics=metrics.METRICS, result_type=run.RunResult, write_log=run.write_log, summarise=evaluate.summarise,
            statistics=evaluate.statistics, report=report.table, table_columns=metrics.TABLE, bounds=metrics.BOUNDS,
            renamed=metrics.RENAMED, layout=Later(lambda: _record().layout),
            record_run=Later(lambda: _record().record_run), record_runs=Later(lambda: _record().record_runs))

    def check_extras(self, cfg: TerrainConfig, extras: dict, force: bool) -> None:
        from workbench.experiments.terrain.products import model
        from workbench.recording import stream

        super().check_extras(cfg, extras, force)
        name = extras.get("model_from")
        if name is not None:
            chosen = [spec.split("=")[0] for spec in cfg.estimators]
            require(name in chosen, f"--model-from {name}: not among this run's estimators ({', '.join(chosen)})")
        folder = model_folder(extras)
        if folder is None:
            return
        require(not folder.exists() or folder.is_dir(), f"--model {folder}: not a folder")
        for n in (*model.FILES, "model.json"):
            stream.check_plain_output(folder / n, force, "halftone model file")

    def export(self, first, stats: dict, extras: dict, force: bool) -> list[str]:
        """``model``: run 0's halftone model as files (:func:`.model.write`)."""
        folder = model_folder(extras)
        lines = super().export(first, stats, extras, force)
        if folder is None:
            return lines
        from workbench.experiments.terrain.products import model

        m = model.from_run(first, extras.get("model_from"))
        model.write(folder, m, first.scene, force)
        stats["model"] = {"folder": str(folder), "model_id": m.model_id, "estimator": m.estimator}
        return [*lines, f"model:     {folder}/ (from {m.estimator}; `workbench measure {folder} --point U,V`)"]


def model_folder(extras: dict) -> Path | None:
    """Where the halftone model goes: ``--model``, else beside the recording (``<out>.model``);
    nowhere with ``--no-model-files`` or without either."""
    if extras.get("model_files") is False:
        return None
    if extras.get("model") is not None:
        return Path(extras["model"]).expanduser()
    rec = extras.get("recording")
    return Path(rec).with_suffix(".model") if rec is not None else None


EXPERIMENT = Terrain()
