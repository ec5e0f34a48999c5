"""The terrain experiment (paper 001) as the workbench sees it: the one object the CLI, the
demo, the Python API and the sweeps use. The flow goes to this package's role modules by
name; here are its declarations and the paper's grid (``--sweep``)."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from workbench.experiments.contract import Demo, Experiment, Preset, split_list
from workbench.experiments.terrain.config import EXTRAS, OPTIONS, SCENARIOS, TerrainConfig
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.scenario import TerrainData


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
               {"size": ("100x100", "200x200", "400x500"), "max_linear": (50.0, 100.0, 200.0),
                "max_angular": (0.001, 0.003, 0.009), "samples": (10, 50, 100)},
               overrides={"hypotheses": "sample"}, estimators="navigation,recurrent-search,recurrent-search-refined"),
    )
    headline = ("dr_fraction", "dx_fraction", "position_error")
    paper_notes = {"dr_fraction": "paper (Fig. 3): mean radial error 40-60 % of the maximum after processing; "
                   "its spread 3-10 % (100x100), 2-8 % (200x200)",
                   "dx_fraction": "paper (Fig. 3): mean |dX| at most 40-60 % of the maximum; spread 6-16 % "
                   "(100x100), 4-13 % (200x200)"}

    # --- the paper's grid (``--sweep DIR``), instead of the usual run
    def _sizes(self, cfg: TerrainConfig, extras: dict) -> tuple[str, ...]:
        from workbench.experiments.terrain import grid

        return split_list(extras["sweep_sizes"]) if extras.get("sweep_sizes") else grid.SIZES

    def check_extras(self, cfg: TerrainConfig, extras: dict, force: bool) -> None:
        if extras.get("sweep") is None:
            return
        from workbench.recording import stream

        for size in self._sizes(cfg, extras):
            replace(cfg, size=size).validate()
        stream.check_plain_output(Path(extras["sweep"]) / "grid.md", force, "grid table")
        stream.check_plain_output(Path(extras["sweep"]) / "grid.csv", force, "grid CSV")

    def instead(self, cfg: TerrainConfig, extras: dict, jobs: int | None, progress) -> dict | None:
        """``sweep``: the paper's grid of image sizes, error levels and functional counts;
        its table, CSV and plots go into that folder."""
        if extras.get("sweep") is None:
            return None
        from workbench.experiments.terrain import grid

        sizes = self._sizes(cfg, extras)
        t0 = time.perf_counter()
        total, done = cfg.runs * len(sizes), [0]

        def tick(n: int) -> None:
            done[0] += n
            progress(done[0], total)

        rows = grid.run_grid(cfg, sizes, jobs, progress=tick)
        written = grid.write(rows, cfg, Path(extras["sweep"]))
        text = (grid.table(rows, cfg) + f"\n\nwritten: {', '.join(str(p) for p in written)}")
        return {"rows": rows, "written": [str(p) for p in written], "_table": text,
                "_lines": [f"{cfg.runs} run(s) per cell in {time.perf_counter() - t0:.1f} s"]}


EXPERIMENT = Terrain()
