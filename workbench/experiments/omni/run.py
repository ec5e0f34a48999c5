"""Configure -> **data -> estimate**: run k's dataset and every estimator on it.

The dataset is simulated (seeded by ``(seed, run)``) or a real MRCLAM log (the same every
run); with ``from_images`` the round images are rendered and the estimators see the image
stage's associated bearings. Its ``grid`` (the bearing epochs, plus one step at least every
``keyframe_every`` seconds) is where every estimator is scored. Evaluation is :mod:`.evaluate`'s.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from workbench.core import experiment as contract
from workbench.core.estimator import Estimator
from workbench.errors import require
from workbench.experiments.omni.algorithms.ekf import HeldInit
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData, keyframe_steps, simulate


@dataclass
class RunResult(contract.RunResult):
    """One run (:class:`~workbench.core.experiment.RunResult`) and its image stage, if any."""

    images: object | None = None  # the image stage (``from_images``): images.ImageStage

    @property
    def grid(self) -> np.ndarray:
        return self.data.grid

    @property
    def keyframes(self):
        """The GTSAM estimators' graph skeleton, if one made it (graph.Keyframes)."""
        return self.products.get("keyframes")


ASSUMED = {"assume_sigma_v": ("--assume-sigma-v", ("bicycle", "unicycle"), 0, float),
           "assume_sigma_gamma_deg": ("--assume-sigma-gamma", ("bicycle",), 1, math.radians),
           "assume_sigma_w_deg": ("--assume-sigma-w", ("unicycle",), 1, math.radians)}
"""What the estimators may be told of the odometry's noise: config field -> its flag, the motion
models that have it, its control's index and the unit's conversion (the bearings' is apart)."""


def assumes(cfg: OmniConfig) -> bool:
    """Whether the estimators are told another noise than the data's (their products, the graph's
    keyframes, then carry it: what is the data's own, the bounds, is made apart)."""
    return any(getattr(cfg, f) is not None for f in (*ASSUMED, "assume_sigma_bearing_deg", "assume_odometry_scale",
                                                      "assume_bearing_scale", "assume_outlier_rate"))


def assumed(data: OmniData, cfg: OmniConfig) -> OmniData:
    """The dataset as the estimators see it (:meth:`.contract.Experiment.assumed`): the odometry's
    speed and steering (bicycle) or yaw-rate (unicycle) noise and the bearings' (each bearing's,
    where a log gave its own) where the config sets what they assume (``--assume-sigma-*``), the
    data's own elsewhere; then the factors on what is stated (``--assume-odometry-scale``,
    ``--assume-bearing-scale``, as sigmas): on the odometry's sigmas and each row's own covariance
    (increments, held controls' variances), on each bearing's own sigma or the one. A one-line
    error for a setting the data's motion model has not."""
    sigma_u, changes = list(data.motion.sigma_u), {}
    for name, (flag, models, index, convert) in ASSUMED.items():
        value = getattr(cfg, name)
        if value is not None:
            require(data.motion.model in models, f"{flag}: this data's odometry is {data.motion.model}, which has "
                                                 "no such noise")
            sigma_u[index] = convert(value)
    if tuple(sigma_u) != tuple(data.motion.sigma_u):
        changes["motion"] = dataclasses.replace(data.motion, sigma_u=tuple(sigma_u))
    if cfg.assume_sigma_bearing_deg is not None:
        changes.update(sigma_bearing=math.radians(cfg.assume_sigma_bearing_deg), meas_sigma=None)
    if cfg.assume_odometry_scale is not None:  # every odometry noise as a sigma: variances x its square
        k = float(cfg.assume_odometry_scale)
        motion = changes.get("motion", data.motion)
        changes["motion"] = dataclasses.replace(motion, sigma_u=tuple(k * s for s in motion.sigma_u),
                                                sigma_q=tuple(k * s for s in motion.sigma_q))
        if data.control_var is not None:
            changes["control_var"] = k * k * np.asarray(data.control_var, float)
    if cfg.assume_bearing_scale is not None:
        k = float(cfg.assume_bearing_scale)
        sigma = changes.get("sigma_bearing", data.sigma_bearing)
        own = changes.get("meas_sigma", data.meas_sigma)
        changes.update(sigma_bearing=k * sigma, meas_sigma=None if own is None else k * np.asarray(own, float))
    return dataclasses.replace(data, **changes) if changes else data


OUTLIER_START = 0.02
"""The outlier share ``--tune-noise`` starts from on a real log (its search runs on the share's
logarithm: a factor of 30 either way reaches 0.07 % and the 50 % cap)."""


def tunable(data: OmniData, cfg: OmniConfig) -> tuple[str, dict[str, float], dict[str, str]]:
    """What ``--tune-noise`` tunes (:mod:`workbench.core.selftune`): by the EKF's likelihood of the
    bearings, the odometry's noise and the bearings', from the data's own values (config units);
    and what it leaves, with why. Where the data state a noise per row (increments' covariances, a
    log's sigma per bearing) a factor on what they state is tuned (``odometry_scale``,
    ``bearing_scale``, from 1): the rows' relative sizes are the log's to say, their scale the
    data's. Elsewhere the sigmas themselves: speed and steering (bicycle) or yaw rate (unicycle).
    On a real log (``mrclam``, ``log``) the bearings' outlier share too (``outlier_rate``, the
    EKF's contaminated Gaussian, ``--assume-outlier-rate``): heavy tails are then fitted as tails,
    not inflated into the odometry's noise."""
    values: dict[str, float] = {}
    left: dict[str, str] = {}
    if data.motion.model == "increments":
        values["odometry_scale"] = 1.0
    else:
        second = "sigma_gamma_deg" if data.motion.model == "bicycle" else "sigma_w_deg"
        values.update(sigma_v=float(data.motion.sigma_u[0]), **{second: math.degrees(data.motion.sigma_u[1])})
    if data.meas_sigma is not None:
        values["bearing_scale"] = 1.0
    else:
        values["sigma_bearing_deg"] = math.degrees(data.sigma_bearing)
    if cfg.scenario in ("mrclam", "log") or cfg.assume_outlier_rate is not None:
        values["outlier_rate"] = OUTLIER_START  # a real log's bearings: misreads, reflections (heavy tails)
    else:
        left["outlier_rate"] = "a simulation's bearings are Gaussian: no outlier model (--assume-outlier-rate adds one)"
    return "ekf", values, left


def hold_rows(estimate: SlamEstimate) -> HeldInit:
    """The EKF's rows of ``estimate`` held (:class:`~.algorithms.ekf.HeldInit`: its landmarks
    initialised where it initialised them), for ``--tune-noise``'s likelihood at other noises."""
    return HeldInit(estimate.init_step)


ODOMETRY = ("odometry_scale", "sigma_v", "sigma_gamma_deg", "sigma_w_deg")
BEARING = ("bearing_scale", "sigma_bearing_deg")


def components(data: OmniData, cfg: OmniConfig, values: dict[str, float]) -> tuple[str, dict[str, list[str]]]:
    """The smoother whose residuals' variance components check ``--tune-noise``'s values
    (:func:`workbench.core.selftune.vce`), and which tuned values scale each of its residual
    groups' noise (:mod:`.residuals`: the odometry between keyframes, the bearings)."""
    return "gtsam-batch", {"odometry": [k for k in values if k in ODOMETRY],
                           "bearing": [k for k in values if k in BEARING]}


def make_data(cfg: OmniConfig, run: int) -> OmniData:
    """The run's dataset, its grid set (with ``from_images``, the image stage's bearings)."""
    return with_stage(cfg, run)[0]


def with_stage(cfg: OmniConfig, run: int, record: bool = False) -> tuple[OmniData, object | None]:
    """The run's dataset and the image stage, if any (``record``: it keeps a frame a second)."""
    stage = None
    if cfg.scenario == "mrclam":
        from workbench.experiments.omni.readers import real

        data = real.load(cfg)
    elif cfg.scenario == "log":
        from workbench.experiments.omni.readers import log

        data = log.read(cfg.data, cfg)
    else:
        data = simulate(cfg, np.random.default_rng([cfg.seed, run]))
    if cfg.from_images:
        from workbench.experiments.omni.imaging import stage as images

        cam = images.MirrorCamera(size=cfg.image_size, noise=cfg.image_noise)
        stage = images.run_stage(data, cam, cfg, np.random.default_rng([cfg.seed, run, 1]),
                                 keep_every=int(round(cfg.bearing_rate)) if record else 0, bad_frames=cfg.bad_frames)
        data = stage.data
    data.grid = keyframe_steps(data, cfg.keyframe_every)
    return data, stage


def run_once(exp: contract.Experiment, cfg: OmniConfig, run: int, estimators: list[Estimator], record: bool = False,
             threads: int = 1) -> RunResult:
    """One run; ``record`` keeps what the recording draws (the image stage's frames,
    initialisation attempts, the graph's map through time)."""
    data, stage = with_stage(cfg, run, record)
    return contract.run_estimators(exp, cfg, run, estimators, data, record, threads, images=stage)


def write_log(data: OmniData, folder, force: bool = False) -> list:
    """A dataset in the open log format (``--export-data``; :mod:`.log`)."""
    from workbench.experiments.omni.readers import log

    return log.write(data, folder, force)
