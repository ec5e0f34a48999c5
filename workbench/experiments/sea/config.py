"""The sea experiment's configuration: the spec's reading of Table 1 as defaults, validated."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from workbench.config.settings import Config, Option, Scenario, apply_scenario, by_scenario, check_assumed
from workbench.errors import require

SCENARIOS: dict[str, Scenario] = {s.name: s for s in (
    Scenario("paper", "the spec's reading of Table 1: a 3 m mast, 72 s, the target at 0.1 m/s^2"),
    Scenario("impulse", "Fig. 5: 1 deg of extra noise on both angles for 40-42 s"),
    Scenario("track-loss", "the object unseen for 30-35 s; the estimators coast"),
    # a real ship is seen from a 20 m mast 1 km abeam for 180 s; it manoeuvres (0.3 m/s^2)
    # its process noise is the data's to say (--tune-noise, on by measurement: the track through the
    # reports accelerates at 6-8 m/s^2 RMS, not the 0.3 assumed; tuned, the EKF's error falls 25 -> 6.6 m)
    Scenario("ais", "a real AIS ship in the Solent as the object, from a 20 m mast 1 km abeam",
             {"height": 20.0, "duration": 180.0, "sigma_acc": 0.3, "tune_noise": True}, real_data=True),
    Scenario("log", "a log of your own (--data FOLDER, the open format of docs/log-formats.md; the truth optional)"),
)}
REGRESSORS = ("measured", "filtered")
OBSERVERS = ("mast", "uav")
ALL_SHIPS = "all"


@dataclass
class SeaConfig(Config):
    """Everything a sea run depends on. Angles in the public fields are in their named units.

    Defaults are ``spec/sea.md``'s reading of Table 1: target velocity (-2.98, -3.12) m/s
    (the paper's printed signs never close the range), the same 0.1 s step for observer and
    target, psi = 50 deg for the angle model; AR orders n = m = 5 without intercept,
    lambda = 1, window M = 120 (Fig. 4, Fig. 5).
    """

    scenario: str = "paper"
    dt: float = 0.1
    duration: float = by_scenario(72.0)
    height: float = by_scenario(3.0)
    sigma_alpha_arcmin: float = 0.88
    sigma_beta_arcmin: float = 1.56
    sigma_observer: float = 1.0
    sigma_acc: float = by_scenario(0.1)
    assume_sigma_alpha_arcmin: float | None = None  # what the estimators assume (None: the data's own)
    assume_sigma_beta_arcmin: float | None = None
    assume_sigma_observer: float | None = None
    assume_sigma_acc: float | None = None
    course_deg: float = 50.0
    observer_velocity: tuple[float, float] = (2.55, 4.33)
    target_start: tuple[float, float] = (400.0, 600.0)
    target_velocity: tuple[float, float] = (-2.98, -3.12)
    order_alpha: int = 5
    order_beta: int = 5
    intercept: bool = False
    lam: float = 1.0
    window: int = 120
    regressors: str = "measured"
    horizon: int = 20
    impulse_start: float = 40.0
    impulse_end: float = 42.0
    impulse_sigma_deg: float = 1.0
    loss_start: float = 30.0
    loss_end: float = 35.0
    ekf_gate: float = 0.0
    robust: bool = False
    prior_speed: float = 10.0
    mmsi: int | str | None = None     # a ship, "all" (every usable ship in turn), None: the most manoeuvring
    data: Path | None = None
    ais_range: float = 1000.0
    ais_max_gap: float = 200.0        # the longest silence between a ship's reports inside a run, s
    observer: str = "mast"            # ais: "mast" (stationary) | "uav" (the real UAV flight, see sea.readers.uav)
    uav_data: Path | None = None
    uav_start: float = 0.0            # where in the UAV flight the run starts, s
    # the image stage (``--from-images``): frames rendered from the truth, angles detected
    from_images: bool = False
    image_size: tuple[int, int] = (1920, 1080)
    fov_deg: float = 70.0
    pan_deg: float | None = None      # camera axis from the course; None: the middle of the run's azimuths
    tilt_deg: float = 0.3             # amplitude of the platform's tilt
    roll_deg: float = 0.3             # amplitude of the platform's roll
    pixel_noise: float = 2.0          # sensor noise, grey levels (1 sigma)
    bad_frames: int = 0               # frames replaced by bad ones (wrong size / type, all sky, empty)
    frame_stride: int = 0             # frames recorded every this many steps; 0: 1 up to 960 px wide, else 2

    def __post_init__(self) -> None:
        apply_scenario(self, SCENARIOS)

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.dt)) + 1

    def memory_bytes(self) -> tuple[float, str]:
        """The memory a run will need (for :mod:`workbench.config.checks`): measured at
        ~20 kB a step for the six estimators of one run (0.24 GB at 720 steps, 0.29 GB at 3600),
        plus ~0.5 kB a step for each run's summary the parent keeps."""
        steps = self.duration / self.dt + 1
        need = 3e8 + 2e4 * steps + 500.0 * steps * self.runs
        return need, f"{steps:.3g} steps (--duration / --dt), {self.runs} run(s)"

    def validate(self) -> SeaConfig:
        """Raise a one-line :class:`WorkbenchError` for any value the experiment cannot use."""
        require(self.scenario in SCENARIOS,
                f"unknown scenario {self.scenario!r}; choose one of {', '.join(SCENARIOS)}")
        require(self.seed >= 0, f"--seed must not be negative, got {self.seed}")
        require(self.runs >= 1, f"--runs must be at least 1, got {self.runs}")
        require(self.dt > 0, f"--dt must be positive, got {self.dt}")
        require(self.duration > 0, f"--duration must be positive, got {self.duration}")
        require(self.height > 0, f"--height must be positive, got {self.height}")
        for name in ("sigma_alpha_arcmin", "sigma_beta_arcmin", "sigma_observer", "sigma_acc",
                     "impulse_sigma_deg"):
            value = getattr(self, name)
            require(value >= 0, f"noise --{_flag(name)} must not be negative, got {value}")
        require(self.sigma_alpha_arcmin > 0 and self.sigma_beta_arcmin > 0,
                "angle noises must be positive: the estimators weight by them")
        check_assumed(self, {"assume_sigma_alpha_arcmin": "--assume-sigma-alpha",
                             "assume_sigma_beta_arcmin": "--assume-sigma-beta",
                             "assume_sigma_observer": "--assume-sigma-observer",
                             "assume_sigma_acc": "--assume-sigma-acc"})
        require(0.0 < self.lam <= 1.0, f"--lam must be in (0, 1], got {self.lam}")
        require(self.order_alpha >= 1 and self.order_beta >= 1, "AR orders must be at least 1")
        params = max(self.order_alpha, self.order_beta) + int(self.intercept)
        require(self.window >= params,
                f"--window {self.window} is shorter than the AR model's {params} parameters")
        require(self.regressors in REGRESSORS,
                f"--regressors must be one of {', '.join(REGRESSORS)}, got {self.regressors!r}")
        require(self.horizon >= 1, f"--horizon must be at least 1, got {self.horizon}")
        require(0.0 <= self.ekf_gate < 1.0, f"--ekf-gate must be in [0, 1), got {self.ekf_gate}")
        require(self.prior_speed > 0, "--prior-speed must be positive")
        require(self.ais_range > 0, "--ais-range must be positive")
        require(self.ais_max_gap > 0, "--ais-max-gap must be positive")
        require(self.mmsi is None or self.mmsi == ALL_SHIPS or (isinstance(self.mmsi, int) and self.mmsi >= 0),
                f"--mmsi must be a ship's number or {ALL_SHIPS!r}, got {self.mmsi!r}")
        require(self.mmsi is None or self.scenario == "ais", "--mmsi needs --scenario ais")
        require(self.scenario != "log" or self.data is not None, "--scenario log needs --data FOLDER (a log folder)")
        require(self.scenario != "log" or not self.from_images, "--from-images renders a simulation: not a log")
        require(self.observer in OBSERVERS, f"--observer must be one of {', '.join(OBSERVERS)}, got {self.observer!r}")
        require(self.observer == "mast" or self.scenario == "ais", "--observer uav needs --scenario ais")
        require(self.uav_start >= 0, f"--uav-start must not be negative, got {self.uav_start}")
        require(self.steps > params + 1, "the run is too short for the AR models")
        require(self.horizon + params + 1 < self.steps,
                f"--horizon {self.horizon} steps leaves nothing to forecast from in a run of {self.steps} steps "
                f"(--duration / --dt; the AR models need {params + 1} before the first forecast)")
        w, h = self.image_size
        require(160 <= w <= 7680 and 90 <= h <= 4320,
                f"--image-size must be within 160x90 .. 7680x4320, got {w}x{h}")
        require(1.0 <= self.fov_deg <= 150.0, f"--fov must be in [1, 150] deg, got {self.fov_deg}")
        for name in ("tilt_deg", "roll_deg", "pixel_noise"):
            require(getattr(self, name) >= 0, f"--{_flag(name.replace('_deg', ''))} must not be negative")
        require(self.tilt_deg <= 10 and self.roll_deg <= 10, "--tilt and --roll are amplitudes of at most 10 deg")
        require(self.frame_stride >= 0, f"--frame-stride must not be negative, got {self.frame_stride}")
        require(0 <= self.bad_frames <= self.steps, f"--bad-frames must be in [0, {self.steps}]")
        return self


def _flag(name: str) -> str:
    return name.replace("_", "-")


def _mmsi(text: str) -> int | str:
    """``--mmsi``: a ship's number, or ``all``."""
    text = str(text).strip()
    if text.lower() == ALL_SHIPS:
        return ALL_SHIPS
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"a ship's number or {ALL_SHIPS!r}, got {text!r}") from None


def _size(text: str) -> tuple[int, int]:
    from workbench.experiments.sea.imaging.camera import parse_size

    return parse_size(text)


OPTIONS: tuple[Option, ...] = (
    Option("lam", "Forgetting factor lambda of algorithm 2, in (0, 1]."),
    Option("window", "Window length M of algorithm 3, in steps.", int),
    Option("order", "AR order n = m of both angle models.", int, sets=("order_alpha", "order_beta")),
    Option("intercept", "Estimate the AR intercepts c0, b0.", bool, switch="--intercept/--no-intercept"),
    Option("regressors", "AR regressors: measured (reading A) | filtered.", str),
    Option("horizon", "Forecast steps l.", int),
    Option("sigma_alpha_arcmin", "Azimuth noise, arcmin.", flag="--sigma-alpha"),
    Option("sigma_beta_arcmin", "Elevation noise, arcmin.", flag="--sigma-beta"),
    Option("sigma_observer", "Observer position noise per axis, m."),
    Option("sigma_acc", "Target acceleration noise, m/s^2."),
    Option("assume_sigma_alpha_arcmin", "What the estimators assume of the azimuth noise, arcmin "
           "[default: the data's, --sigma-alpha].", flag="--assume-sigma-alpha"),
    Option("assume_sigma_beta_arcmin", "What the estimators assume of the elevation noise, arcmin "
           "[default: the data's].", flag="--assume-sigma-beta"),
    Option("assume_sigma_observer", "What the estimators assume of the observer position noise, m "
           "[default: the data's]."),
    Option("assume_sigma_acc", "What the estimators assume of the target acceleration noise (their process "
           "noise), m/s^2 [default: the data's, --sigma-acc]."),
    Option("height", "Camera height h, m."),
    Option("duration", "Run length, s."),
    Option("dt", "Time step, s."),
    Option("ekf_gate", "EKF chi-square gate probability (0 = off)."),
    Option("robust", "Huber noise model in the GTSAM factors.", bool, switch="--robust/--no-robust"),
    Option("mmsi", "ais: the ship, or 'all' (every ship with a long enough track, a row each) "
                   "[default: the most manoeuvring one].", str, parse=_mmsi),
    Option("data", "ais: the AIS CSV [default: <data root>/ais/...]; log: the log folder.", Path),
    Option("ais_range", "ais: camera stand-off from the track, m."),
    Option("ais_max_gap", "ais: the longest gap between a ship's reports inside a run, s."),
    Option("observer", "ais: the camera's platform: mast (stationary) | uav (the real UAV flight).", str),
    Option("uav_data", "ais, --observer uav: the UAV log [default: <data root>/ais/UAV_Rot.csv].", Path),
    Option("uav_start", "ais, --observer uav: where in the flight the run starts, s."),
    Option("from_images", "Render camera frames and take the angles from them.", bool,
           switch="--from-images/--from-angles"),
    Option("image_size", "Frame size WIDTHxHEIGHT (70 deg wide).", str, parse=_size),
    Option("frame_stride", "Record every n-th frame [0: 1 up to 960 px wide, else 2].", int),
    Option("bad_frames", "Replace this many frames by bad ones (size, type, sky, empty).", int),
    Option("tilt_deg", "Platform tilt amplitude, deg.", flag="--tilt"),
    Option("roll_deg", "Platform roll amplitude, deg.", flag="--roll"),
    Option("pixel_noise", "Sensor noise, grey levels."),
)
"""The sea experiment's own command-line options (the shared ones are the CLI's)."""
