"""The terrain experiment's configuration: the paper's error levels and image sizes, and the
choices it leaves open (flight height, focal length, terrain, texture), documented and validated.

Defaults (``spec/terrain.md`` says to choose and document them):

* flight height 1500 m above the mean terrain, focal length 150 mm, frame 160 x 120 mm, so the
  footprint is 1600 x 1200 m and the paper's sizes give its ground resolutions: 100 x 100 ->
  16 x 12 m (paper ~19 x 12), 200 x 200 -> 8 x 6 m, 400 x 500 -> 4 x 2.4 m (paper ~4 x 2);
* 65 % overlap along X (the paper's 60-70 %), 100 m/s, so the exposures are 5.6 s apart;
* relief with a 100 m standard deviation over hills, ridges and 60 m detail; a texture with
  a 30 m correlation length at several scales, Lambertian shading; image noise 0.01 (of 1);
* navigation errors uniform up to 100 m and 0.003 rad (the headline case), velocity errors
  up to 1 m/s in the common-error mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from workbench.config.settings import Config, Option, Scenario, apply_scenario, by_scenario
from workbench.errors import require
from workbench.loading import split_list

# the ngi frames are 640 x 1152: a quarter of each side keeps their aspect and ~24 m pixels
SCENARIOS: dict[str, Scenario] = {s.name: s for s in (
    Scenario("synthetic", "a synthetic terrain and texture under a simulated pair (1500 m, 150 mm, 65 % overlap)"),
    Scenario("ngi", "two real NGI aerial frames (Intergraph DMC, ~5 km up) and their DEM",
             {"size": "160x288", "radiometry": "local"}, real_data=True),
    Scenario("log", "a pair of your own (--data FOLDER, the open format of docs/log-formats.md; the truth optional)",
             {"radiometry": "local"}),
)}
MODES = ("common", "ii-only")
DISTRIBUTIONS = ("uniform", "gaussian", "maximum")
HYPOTHESES = ("grid", "sample")
BANKS = ("batch", "literal")
RADIOMETRY = ("local", "moments", "none")
NGI_FRAMES = ("0182", "0184", "0251", "0253")
MAX_PIXELS = 2_000_000


def parse_size(text: str) -> tuple[int, int]:
    """``"200x200"`` -> (width, height) in pixels."""
    parts = str(text).lower().replace(" ", "").split("x")
    require(len(parts) == 2 and all(p.isdigit() for p in parts),
            f"--size must look like WIDTHxHEIGHT, e.g. 200x200 (got {text!r})")
    w, h = int(parts[0]), int(parts[1])
    require(w >= 16 and h >= 16, f"--size must be at least 16x16 pixels (got {text})")
    return w, h


@dataclass
class TerrainConfig(Config):
    """Everything a terrain run depends on; lengths in m, angles in rad, focal length in mm."""

    scenario: str = "synthetic"
    size: str = by_scenario("200x200")
    mode: str = "common"
    distribution: str = "uniform"
    max_linear: float = 100.0
    max_angular: float = 0.003
    max_velocity: float = 1.0
    # the flight and the camera (synthetic scene)
    height: float = 1500.0
    focal_mm: float = 150.0
    sensor_mm: tuple[float, float] = (160.0, 120.0)
    overlap: float = 0.65
    speed: float = 100.0
    # the terrain and its texture (synthetic scene)
    relief: float = 100.0
    dem_spacing: float = 10.0
    texture_scale: float = 30.0
    image_noise: float = 0.01
    supersample: int = 2
    # recurrent-search estimation
    hypotheses: str = "grid"
    levels_linear: int = 5
    levels_angular: int = 3
    samples: int = 50
    node_step: int = 1
    sigma_r: float = 0.05
    radiometry: str = by_scenario("none")  # the real frames: "local" (radiometry.py says why)
    bank: str = "batch"
    chunk_mb: float = 256.0
    # the GTSAM baseline
    features: int = 800
    dem_sigma: float = 5.0
    # the real scene
    data: Path | None = None
    pair: tuple[str, str] = ("0182", "0184")

    def __post_init__(self) -> None:
        apply_scenario(self, SCENARIOS)

    @property
    def image_size(self) -> tuple[int, int]:
        return parse_size(self.size)

    @property
    def baseline(self) -> float:
        """Distance between the exposures along X (m): (1 - overlap) times the footprint."""
        return (1.0 - self.overlap) * self.height * self.sensor_mm[0] / self.focal_mm

    @property
    def interval(self) -> float:
        """Time between the exposures (s): the dynamics A's step."""
        return self.baseline / self.speed

    def memory_bytes(self) -> tuple[float, str]:
        """The memory a synthetic run will need (for :mod:`workbench.config.checks`): the
        DEM and the albedo raster over both footprints and the error margins (as
        :func:`~workbench.experiments.terrain.scenario.synthetic_scene` sizes them; a few float64
        arrays of each while they are made), and the ray casting's arrays per pixel. The real
        pair is sized by its files."""
        if self.scenario != "synthetic":
            return 3e8, "the real frames"
        w, h = self.image_size
        foot_x = self.height * self.sensor_mm[0] / self.focal_mm
        foot_y = self.height * self.sensor_mm[1] / self.focal_mm
        margin = 3.0 * self.max_linear + 0.3 * foot_x + 3.0 * self.max_angular * self.height + 3 * self.relief
        span_x, span_y = self.baseline + foot_x + 2 * margin, foot_y + 2 * margin
        dem = (span_x / self.dem_spacing + 1) * (span_y / self.dem_spacing + 1)
        texel = max(1.0, min(foot_x / w, foot_y / h) / 2.0)
        albedo = (span_x / texel + 1) * (span_y / texel + 1)
        need = 3e8 + 8 * 8.0 * (dem + albedo) + 8 * 30.0 * w * h
        return need, f"a {span_x / 1e3:.3g} x {span_y / 1e3:.3g} km DEM at {self.dem_spacing:g} m and its texture " \
                     f"(--height, --focal, --dem-spacing), {w}x{h} pixels"

    def validate(self) -> TerrainConfig:
        """Raise a one-line :class:`WorkbenchError` on any value out of range."""
        require(self.scenario in SCENARIOS, f"unknown scenario {self.scenario!r}; one of {', '.join(SCENARIOS)}")
        require(self.seed >= 0, f"--seed must not be negative (got {self.seed})")
        require(self.mode in MODES, f"unknown error mode {self.mode!r}; one of {', '.join(MODES)}")
        require(self.distribution in DISTRIBUTIONS,
                f"unknown error distribution {self.distribution!r}; one of {', '.join(DISTRIBUTIONS)}")
        require(self.hypotheses in HYPOTHESES, f"--hypotheses must be one of {', '.join(HYPOTHESES)}")
        require(self.bank in BANKS, f"--bank must be one of {', '.join(BANKS)}")
        require(self.radiometry in RADIOMETRY, f"--radiometry must be one of {', '.join(RADIOMETRY)}")
        require(self.runs >= 1, f"--runs must be at least 1 (got {self.runs})")
        for name in ("max_linear", "max_angular"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0.0,
                    f"--{name.replace('_', '-')} must be a positive number (got {value})")
        require(self.max_angular < 0.3, f"--max-angular is in radians and must be below 0.3 (got {self.max_angular})")
        require(math.isfinite(self.max_velocity) and self.max_velocity >= 0.0,
                f"--max-velocity must be >= 0 (got {self.max_velocity})")
        for name in ("height", "focal_mm", "speed", "dem_spacing", "texture_scale", "sigma_r", "chunk_mb",
                     "dem_sigma"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0.0,
                    f"--{name.replace('_', '-')} must be positive (got {value})")
        require(all(s > 0 for s in self.sensor_mm), "the sensor size must be positive")
        require(0.2 <= self.overlap < 0.95, f"--overlap must be in [0.2, 0.95) (got {self.overlap})")
        require(self.relief >= 0.0, f"--relief must be >= 0 (got {self.relief})")
        require(self.image_noise >= 0.0, f"--image-noise must be >= 0 (got {self.image_noise})")
        require(1 <= self.supersample <= 4, f"--supersample must be 1..4 (got {self.supersample})")
        require(self.levels_linear >= 1 and self.levels_angular >= 1, "grid levels must be at least 1")
        require(self.levels_linear ** 3 * self.levels_angular ** 3 <= 1_000_000, "the grid is over a million cells")
        require(1 <= self.samples <= 100_000, f"--samples must be 1..100000 (got {self.samples})")
        require(self.node_step >= 1, f"--node-step must be at least 1 (got {self.node_step})")
        require(self.features >= 20, f"--features must be at least 20 (got {self.features})")
        w, h = self.image_size
        require(w * h <= MAX_PIXELS, f"--size {self.size} is over {MAX_PIXELS} pixels")
        require(self.scenario != "log" or self.data is not None, "--scenario log needs --data FOLDER (a log folder)")
        if self.scenario == "ngi":
            require(len(self.pair) == 2 and self.pair[0] != self.pair[1] and all(p in NGI_FRAMES for p in self.pair),
                    f"--pair must name two different frames of {', '.join(NGI_FRAMES)}")
        return self


OPTIONS: tuple[Option, ...] = (
    Option("mode", "Error mode: common (one process, dynamics A) | ii-only.", str),
    Option("size", "Image size WIDTHxHEIGHT (the paper: 100x100, 200x200, 400x500).", str),
    Option("max_linear", "Maximum linear navigation error, m."),
    Option("max_angular", "Maximum angular navigation error, rad."),
    Option("max_velocity", "common mode: maximum velocity error, m/s."),
    Option("distribution", "Errors: uniform | gaussian (sigma = max/3) | maximum (+-max).", str),
    Option("hypotheses", "Hypotheses: grid (full) | sample (N drawn in the cube).", str),
    Option("levels_linear", "grid: cells per linear axis.", int),
    Option("levels_angular", "grid: cells per angular axis.", int),
    Option("samples", "sample: the number of functionals N.", int),
    Option("node_step", "Node step delta on image I, pixels.", int),
    Option("sigma_r", "Irradiance noise sigma of the filters (R = sigma^2)."),
    Option("radiometry", "Image II onto image I's irradiance scale: local (each image's slow "
           "brightness variation removed, then moments) | moments (affine, matched over the "
           "overlap) | none (the paper's (2)).", str),
    Option("bank", "Filter bank: batch (closed form, compiled) | literal (node by node).", str),
    Option("chunk_mb", "literal bank: memory budget of a chunk of hypotheses, MB."),
    Option("height", "synthetic: flight height over the mean terrain, m."),
    Option("focal_mm", "synthetic: focal length, mm (frame 160 x 120 mm).", flag="--focal"),
    Option("overlap", "synthetic: overlap of the pair along the flight."),
    Option("relief", "synthetic: standard deviation of the terrain heights, m."),
    Option("texture_scale", "synthetic: correlation length of the texture, m."),
    Option("image_noise", "synthetic: image noise sigma (irradiance 0..1)."),
    Option("data", "ngi: the folder [default: <data root>/ngi]; log: the log folder.", Path),
    Option("pair", "ngi: the two frames, image I first.", str, parse=split_list),
)
"""The terrain experiment's own command-line options (the shared ones are the CLI's)."""


EXTRAS: tuple[Option, ...] = (
    Option("model", "Write run 0's halftone model (orthophoto, ground X/Y/H and their sigmas as GeoTIFFs, the "
           "textured mesh; `workbench measure FOLDER` measures in it) into this folder [beside the recording, "
           "<out>.model].", Path),
    Option("model_files", "Write the halftone model's files (--no-model-files: only the recording).", bool,
           switch="--model-files/--no-model-files"),
    Option("model_from", "The estimator whose orientation builds the model [the first of gtsam-ba, "
           "recurrent-search-iterated, recurrent-search-refined with a covariance].", str),
)
