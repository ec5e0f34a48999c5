"""The terrain experiment (paper 001) as the workbench sees it: the one object the CLI, the
demo, the Python API and the sweeps use. The flow goes to this package's role modules by
name; here are its declarations (the paper's grid is the sweep preset ``paper-grid``)."""

from __future__ import annotations

from workbench.experiments.contract import Demo, Experiment, Preset
from workbench.experiments.terrain import grid
from workbench.experiments.terrain.config import OPTIONS, SCENARIOS, TerrainConfig
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.scenario import TerrainData


class Terrain(Experiment):
    name = "terrain"
    description = ("paper 001: aerial stereo pair + DEM; recurrent-search estimation (a Kalman filter bank "
                   "over error hypotheses) against GTSAM bundle adjustment; synthetic and the real NGI frames")
    config_type = TerrainConfig
    scenarios = SCENARIOS
    options = OPTIONS
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
               report="workbench.experiments.terrain.grid:from_sweep"),
    )
    headline = ("dr_fraction", "dx_fraction", "position_error")
    compared = ()
    paper_notes = {"dr_fraction": "paper (Fig. 3): mean radial error 40-60 % of the maximum after processing; "
                   "its spread 3-10 % (100x100), 2-8 % (200x200)",
                   "dx_fraction": "paper (Fig. 3): mean |dX| at most 40-60 % of the maximum; spread 6-16 % "
                   "(100x100), 4-13 % (200x200)"}


EXPERIMENT = Terrain()
