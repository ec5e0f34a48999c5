"""The omni experiment's configuration: the paper's simulation and the spec's choices, validated.

The paper (seed 000) gives: 80 x 80 m, 3 m/s for 500 s, dt = 0.025 s, sigma_V = 0.1 m/s,
sigma_gamma = 3 deg (white per step), sigma_theta = 1 deg. ``spec/omni.md`` chooses what it
leaves open, all options here: L = 4 m, bearings at 5 Hz, 24 wall lines + 8 pillars, 360 deg
field of view, 30 m range, a square route 12 m inside the walls, the start pose known.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from workbench.config.settings import Config, Option, Scenario, apply_scenario, by_scenario, check_assumed
from workbench.errors import require

IMAGE_SIGMA_BEARING_DEG = 0.3

# MRCLAM: a forward camera (bearings span about +-33 deg, lines up to a few metres away),
# odometry at ~67 Hz that behaves like commanded velocity, landmarks seen intermittently.
# Odometry noise as densities (steps vary from 0.01 to 1 s): 2 deg/s/sqrt(Hz) matches the
# heading's random walk of ~2 deg/sqrt(s) over blind stretches. Landmarks wait for 15 deg
# of parallax (the paper's UT gate almost never passes through a 66 deg window: its sigma
# points fall behind a view), a candidate is kept 30 s, bearings are NIS-gated at 0.99 (the
# EKF on its innovation, the graph against iSAM2's own newest pose and landmark marginals
# carried on with the odometry: misread barcodes, robot 3 at 255 s). iSAM2 runs alone, without
# periodic whole-graph LM passes (``lm_every`` 0; issue 36: they made a log's cost grow as its
# square, 4.4x for a log twice as long): its runaways came from a gate and held rays that
# followed a drifting chain, and a runaway still gets one damped pass (:class:`.graph._Incremental`).
BATCH_STARTS = ("odometry", "grown", "isam2", "ekf", "gnc")
"""Where gtsam-batch may start (:func:`.graph.batch` keeps the start of lowest cost on the data)."""
ODOMETRY_BETWEEN = ("switch", "hold")
"""How a real log's velocity command is read between two logged rows (:mod:`.real`)."""

LOG_DEFAULTS = {"settle": 0.0, "graph_parallax_deg": 15.0, "lm_every": 0.0, "drop_after": 30.0,
                "min_parallax_deg": 15.0, "nis_gate": 0.99, "ekf_init": "linear", "ekf_second_order": True,
                "batch_starts": "isam2,grown,odometry"}
"""A log's estimator settings: a real robot's (MRCLAM's, as above) without its camera's; the
odometry's and bearings' noise come from the log's manifest."""

SCENARIOS: dict[str, Scenario] = {s.name: s for s in (
    Scenario("paper", "the paper's 500 s simulation: 80 x 80 m room, 24 wall lines and 8 pillars, 3 m/s"),
    Scenario("mrclam", "the real robots of UTIAS MRCLAM dataset 6 (unicycle odometry, forward camera)",
             {"fov_deg": 70.0, "max_range": 6.0, "settle": 0.0, "graph_parallax_deg": 15.0,
              "sigma_v": 0.02, "sigma_w_deg": 2.0, "noise_per_second": True, "lm_every": 0.0,
              "drop_after": 30.0, "min_parallax_deg": 15.0, "nis_gate": 0.99, "ekf_init": "linear",
              "ekf_second_order": True,
              "batch_starts": "isam2,grown,odometry"}, real_data=True),
    Scenario("log", "a log of your own (--data FOLDER, the open format of docs/log-formats.md; the truth optional)",
             LOG_DEFAULTS),
)}


@dataclass
class OmniConfig(Config):
    """Everything an omni run depends on; angles in the public fields are in degrees."""

    scenario: str = "paper"
    # the paper's simulation
    room: float = 80.0
    inset: float = 12.0
    speed: float = 3.0
    duration: float = 500.0
    dt: float = 0.025
    wheelbase: float = 4.0
    bearing_rate: float = 5.0
    wall_lines: int = 24
    pillars: int = 8
    fov_deg: float = by_scenario(360.0)
    max_range: float = by_scenario(30.0)
    sigma_v: float = by_scenario(0.1)
    sigma_gamma_deg: float = 3.0
    sigma_bearing_deg: float = None  # [1; from images 0.3]
    sigma_q: float = 0.0
    # what the estimators assume instead of the data's own noise (None: the data's)
    assume_sigma_v: float | None = None
    assume_sigma_gamma_deg: float | None = None   # the paper's bicycle: steering
    assume_sigma_w_deg: float | None = None       # a unicycle (MRCLAM, logs): yaw rate
    assume_sigma_bearing_deg: float | None = None
    # factors on the noise the data state (a log's own covariances too), as sigmas: odometry, bearings
    assume_odometry_scale: float | None = None
    assume_bearing_scale: float | None = None
    assume_outlier_rate: float | None = None     # a contaminated Gaussian's outlier share of the bearings
    # the landmark initialiser (1)-(5)
    skew_gate: float = 0.3
    min_parallax_deg: float = by_scenario(2.0)
    drop_after: float = by_scenario(1.0)
    kappa: float = 1.0
    # the filters and the graph
    nis_gate: float = by_scenario(0.0)
    graph_parallax_deg: float = by_scenario(5.0)
    relin_threshold: float = 0.1
    keyframe_every: float = 1.0
    settle: float = by_scenario(80.0)
    # the image stage (paper only)
    from_images: bool = False
    image_size: int = 320
    image_noise: float = 4.0
    bad_frames: int = 0
    # the real robots
    data: Path | None = None
    robot: int = 1
    sigma_w_deg: float = by_scenario(5.0)
    noise_per_second: bool = by_scenario(False)
    lm_every: float = by_scenario(0.0)
    huber: float = 0.0
    batch_huber: float = 0.0
    ekf_init: str = by_scenario("ut")
    ekf_second_order: bool = by_scenario(False)
    start_time: float | None = None
    end_time: float | None = None
    odometry_between: str = "switch"
    batch_starts: str = by_scenario("odometry,isam2")

    def __post_init__(self) -> None:
        if self.sigma_bearing_deg is None:
            # the image stage measures bearings to ~0.07 deg (320 px); the estimators (and the
            # association's gates) are told 0.3 deg. With the simulation's 1 deg the gates are so
            # wide that neighbouring lines get confused: over 250 s, 76 % of detections went to
            # their own line in 72 tracks at 1 deg, 90 % in 36 tracks at 0.3 deg. With the track
            # management of associate.py (500 s, seed 6): 99.97 % in 32 tracks at 0.3 deg, 99.9 %
            # in 32 at 0.1 deg, 90 % in 30 at 1 deg (wide gates still confuse neighbours there)
            self.sigma_bearing_deg = IMAGE_SIGMA_BEARING_DEG if self.from_images else 1.0
        apply_scenario(self, SCENARIOS)

    @property
    def starts(self) -> list[str]:
        """The batch's starts ``--batch-starts`` names, in order (the first wins a tie)."""
        return [n.strip() for n in self.batch_starts.split(",") if n.strip()]

    @property
    def sigma_gamma(self) -> float:
        return math.radians(self.sigma_gamma_deg)

    @property
    def sigma_bearing(self) -> float:
        return math.radians(self.sigma_bearing_deg)

    def memory_bytes(self) -> tuple[float, str]:
        """The memory a run will need (for :mod:`workbench.config.checks`): ~0.5 kB a
        simulation step (measured: +7 MB from 4,000 to 20,000 steps), ~20 kB a keyframe (the
        graphs and their marginals), and each run's summary on the keyframe grid (five
        estimators, a dozen numbers each) that the parent keeps; with ``N`` landmarks (the
        simulation's wall lines and pillars), the EKF's ``(3 + 2N)^2`` covariance and, at every
        keyframe, a bearing and a mapped mean and covariance per landmark (~100 bytes)."""
        steps = self.duration / self.dt + 1
        keyframes = self.duration * (self.bearing_rate + 1.0 / self.keyframe_every) + 1
        images = keyframes * self.image_size ** 2 if self.from_images else 0.0
        n = float(self.wall_lines + self.pillars) if self.scenario == "paper" else 15.0
        need = (3e8 + 500.0 * steps + 2e4 * keyframes + images + 500.0 * keyframes * self.runs
                + 8.0 * (3.0 + 2.0 * n) ** 2 + 100.0 * n * keyframes)
        return need, (f"{steps:.3g} steps (--duration / --dt), {keyframes:.3g} keyframes, {n:.3g} landmarks "
                      f"(--wall-lines + --pillars), {self.runs} run(s)")

    def validate(self) -> OmniConfig:
        """Raise a one-line :class:`WorkbenchError` on any value out of range."""
        require(self.scenario in SCENARIOS, f"unknown scenario {self.scenario!r}; one of {', '.join(SCENARIOS)}")
        require(self.runs >= 1, f"--runs must be at least 1 (got {self.runs})")
        require(self.seed >= 0, f"--seed must not be negative (got {self.seed})")
        for name in ("sigma_v", "sigma_gamma_deg", "sigma_bearing_deg", "sigma_q", "sigma_w_deg"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0.0,
                    f"--{name.replace('_', '-')} must be a non-negative number (got {value})")
        require(self.sigma_bearing_deg > 0.0, "--sigma-bearing must be positive (bearings need a noise model)")
        check_assumed(self, {"assume_sigma_v": "--assume-sigma-v", "assume_sigma_gamma_deg": "--assume-sigma-gamma",
                             "assume_sigma_w_deg": "--assume-sigma-w",
                             "assume_sigma_bearing_deg": "--assume-sigma-bearing",
                             "assume_odometry_scale": "--assume-odometry-scale",
                             "assume_bearing_scale": "--assume-bearing-scale",
                             "assume_outlier_rate": "--assume-outlier-rate"})
        require(self.assume_outlier_rate is None or self.assume_outlier_rate < 0.5,
                f"--assume-outlier-rate must be below 0.5 (got {self.assume_outlier_rate})")
        for name in ("room", "speed", "duration", "dt", "wheelbase", "bearing_rate", "max_range",
                     "drop_after", "keyframe_every"):
            value = getattr(self, name)
            require(math.isfinite(value) and value > 0.0, f"--{name.replace('_', '-')} must be positive (got {value})")
        require(0.0 < self.inset < self.room / 2, f"--inset must be in (0, room/2) (got {self.inset})")
        require(0.0 < self.fov_deg <= 360.0, f"--fov must be in (0, 360] deg (got {self.fov_deg})")
        require(0.0 < self.skew_gate <= 2.0, f"--skew-gate must be in (0, 2] (got {self.skew_gate})")
        require(0.0 <= self.min_parallax_deg < 90.0,
                f"--min-parallax must be in [0, 90) deg (got {self.min_parallax_deg})")
        require(0.0 < self.graph_parallax_deg < 90.0,
                f"--graph-parallax must be in (0, 90) deg (got {self.graph_parallax_deg})")
        require(0.0 <= self.nis_gate < 1.0, f"--nis-gate must be a probability in [0, 1) (got {self.nis_gate})")
        require(self.kappa >= 0.0, f"--kappa must be >= 0 so that every UT weight is non-negative (got {self.kappa})")
        require(self.relin_threshold > 0.0, f"--relin-threshold must be positive (got {self.relin_threshold})")
        require(self.settle >= 0.0, f"--settle must be >= 0 (got {self.settle})")
        require(self.wall_lines >= 0 and self.pillars >= 0 and self.wall_lines + self.pillars >= 2,
                "need at least two landmarks (--wall-lines + --pillars)")
        require(self.dt <= 1.0 / self.bearing_rate, "--dt must not exceed the bearing period 1/--bearing-rate")
        require(self.scenario != "log" or self.data is not None, "--scenario log needs --data FOLDER (a log folder)")
        require(not self.from_images or self.scenario == "paper",
                "--from-images renders the simulation's round images: it needs --scenario paper")
        require(self.bad_frames >= 0, f"--bad-frames must be >= 0 (got {self.bad_frames})")
        require(self.image_size >= 64, f"--image-size must be at least 64 px (got {self.image_size})")
        require(math.isfinite(self.image_noise) and self.image_noise >= 0.0,
                f"--image-noise must be a non-negative number (got {self.image_noise})")
        if self.scenario == "paper":
            require(self.duration / self.dt <= 2_000_000, "--duration / --dt is over 2 million steps")
        require(math.isfinite(self.lm_every) and self.lm_every >= 0.0,
                f"--lm-every must be >= 0 s (got {self.lm_every})")
        require(math.isfinite(self.huber) and self.huber >= 0.0, f"--huber must be >= 0 sigmas (got {self.huber})")
        require(math.isfinite(self.batch_huber) and self.batch_huber >= 0.0,
                f"--batch-huber must be >= 0 sigmas (got {self.batch_huber})")
        require(self.ekf_init in ("ut", "linear"), f"--ekf-init must be ut or linear (got {self.ekf_init!r})")
        starts = self.starts
        require(starts and set(starts) <= set(BATCH_STARTS) and len(set(starts)) == len(starts),
                f"--batch-starts must name one or more of {', '.join(BATCH_STARTS)}, each once "
                f"(got {self.batch_starts!r})")
        require(starts[0] != "gnc", "--batch-starts: gnc refines the cheapest start solved before it, so it cannot "
                f"come first "
                f"(got {self.batch_starts!r})")
        require(self.odometry_between in ODOMETRY_BETWEEN,
                f"--odometry-between must be one of {', '.join(ODOMETRY_BETWEEN)} (got {self.odometry_between!r})")
        return self


def make_config(scenario: str, **given) -> OmniConfig:
    """A config with the scenario's defaults under what was given (``None`` = not given)."""
    return OmniConfig(scenario=scenario, **{k: v for k, v in given.items() if v is not None})


OPTIONS: tuple[Option, ...] = (
    Option("duration", "paper: run length, s."),
    Option("dt", "paper: odometry step, s."),
    Option("speed", "paper: vehicle speed, m/s."),
    Option("wheelbase", "paper: vehicle length L of the bicycle model, m."),
    Option("bearing_rate", "paper: bearings per second."),
    Option("wall_lines", "paper: vertical lines on the walls.", int),
    Option("pillars", "paper: pillars inside the route.", int),
    Option("fov_deg", "Camera field of view, deg.", flag="--fov"),
    Option("max_range", "Longest sighting, m (mrclam: drawing only)."),
    Option("sigma_v", "Odometer speed noise per step, m/s."),
    Option("sigma_gamma_deg", "paper: steering noise per step, deg.", flag="--sigma-gamma"),
    Option("sigma_w_deg", "mrclam: yaw-rate noise per step, deg/s.", flag="--sigma-w"),
    Option("sigma_q", "Extra process noise Q per step and axis (m, rad)."),
    Option("sigma_bearing_deg", "Bearing noise, deg [1; --from-images 0.3].", flag="--sigma-bearing"),
    Option("assume_sigma_v", "What the estimators assume of the speed noise, m/s [default: the data's, --sigma-v]."),
    Option("assume_sigma_gamma_deg", "paper: what the estimators assume of the steering noise, deg [default: the "
           "data's].", flag="--assume-sigma-gamma"),
    Option("assume_sigma_w_deg", "mrclam, log: what the estimators assume of the yaw-rate noise, deg/s [default: "
           "the data's].", flag="--assume-sigma-w"),
    Option("assume_sigma_bearing_deg", "What the estimators assume of the bearing noise, deg, for every bearing "
           "[default: the data's].", flag="--assume-sigma-bearing"),
    Option("assume_odometry_scale", "A factor on the odometry's noise the estimators assume, as a sigma: on "
           "its sigmas and on each row's own covariance a log gives (increments), variances x its square "
           "[default: 1]."),
    Option("assume_bearing_scale", "A factor on the bearings' noise the estimators assume, as a sigma: on each "
           "bearing's own sigma a log gives, or on --sigma-bearing [default: 1]."),
    Option("assume_outlier_rate", "The share of bearings the EKF takes for outliers, uniform over the circle "
           "(a contaminated Gaussian): it leaves out a bearing more likely an outlier than not (instead of "
           "--nis-gate), and its likelihood is the mixture's [default: none]."),
    Option("skew_gate", "Initialise a landmark when |skewness| < this."),
    Option("min_parallax_deg", "... and its rays' parallax is at least this, deg.", flag="--min-parallax"),
    Option("drop_after", "Forget a pending landmark unseen this long, s."),
    Option("kappa", "UT kappa (>= 0 keeps the weights non-negative)."),
    Option("nis_gate", "EKF chi-square gate probability per bearing (0 = off)."),
    Option("graph_parallax_deg", "GTSAM: insert a landmark at this parallax, deg.", flag="--graph-parallax"),
    Option("relin_threshold", "iSAM2 relinearisation threshold."),
    Option("settle", "Errors count from this time on, s."),
    Option("data", "mrclam: the dataset folder [default: <data root>/mrclam6]; log: the log folder.", Path),
    Option("robot", "mrclam: the robot, 1..5 where the folder has it.", int),
    Option("start_time", "mrclam: start this many seconds into the log."),
    Option("end_time", "mrclam: end this many seconds into the log."),
    Option("odometry_between", "mrclam: the command between two logged ones: switch (at an unknown "
           "time: their mean, with the variance of not knowing when) | hold (the earlier one).", str),
    Option("noise_per_second", "Odometry noise as densities or per step.", bool,
           switch="--noise-per-second/--noise-per-step"),
    Option("lm_every", "GTSAM: a damped whole-graph LM pass every this many s besides those at a run-away "
           "(0, the default: only at a run-away; a period makes the cost grow as the log's square)."),
    Option("ekf_init", "EKF landmark init: ut (the paper's gate) | linear.", str),
    Option("ekf_second_order", "EKF: second-order bearing terms in the update.", bool,
           switch="--second-order/--first-order"),
    Option("batch_starts", "gtsam-batch: solve from these in turn while the last fit fails its chi-square test, "
           "keep the lowest cost on the data: odometry, grown (the graph grown with an LM pass every --lm-every s, "
           "20 where that is 0), isam2, ekf (their answers), gnc (graduated non-convexity from the cheapest "
           "start solved before it).", str),
    Option("huber", "GTSAM: Huber threshold on bearing factors (0 = off)."),
    Option("batch_huber", "gtsam-batch alone: Huber threshold on its bearing factors, in sigmas (0 = off; "
           "iSAM2 and the starts it solves from stay Gaussian, and each start's fit test is the Gaussian "
           "chi-square of the residuals)."),
    Option("from_images", "paper: render round images and estimate from their bearings.", bool,
           switch="--from-images/--from-bearings"),
    Option("image_size", "Round image size, px.", int),
    Option("image_noise", "Round image pixel noise, grey levels."),
    Option("bad_frames", "--from-images: replace this many frames by bad ones.", int),
)
"""The omni experiment's own command-line options (the shared ones are the CLI's)."""

EXTRAS: tuple[Option, ...] = (
    Option("export_tum", "Write run 0's trajectories in TUM format into this folder.", Path),
)
