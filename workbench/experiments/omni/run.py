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

from workbench.errors import require
from workbench.experiments import contract
from workbench.experiments.estimator import Estimator
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData, keyframe_steps, simulate


@dataclass
class RunResult(contract.RunResult):
    """One run (:class:`~workbench.experiments.contract.RunResult`) and its image stage, if any."""

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
    return any(getattr(cfg, f) is not None for f in (*ASSUMED, "assume_sigma_bearing_deg"))


def assumed(data: OmniData, cfg: OmniConfig) -> OmniData:
    """The dataset as the estimators see it (:meth:`.contract.Experiment.assumed`): the odometry's
    speed and steering (bicycle) or yaw-rate (unicycle) noise and the bearings' (each bearing's,
    where a log gave its own) where the config sets what they assume (``--assume-sigma-*``), the
    data's own elsewhere. A one-line error for a setting the data's motion model has not."""
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
    return dataclasses.replace(data, **changes) if changes else data


def tunable(data: OmniData, cfg: OmniConfig) -> tuple[str, dict[str, float], dict[str, str]]:
    """What ``--tune-noise`` tunes (:mod:`workbench.tuning.selftune`): by the EKF's likelihood of the
    bearings, the odometry's two noises (speed and steering, or speed and yaw rate) and the
    bearings', from the data's own values (config units); and what it leaves, with why."""
    second = "sigma_gamma_deg" if data.motion.model == "bicycle" else "sigma_w_deg"
    values = {"sigma_v": float(data.motion.sigma_u[0]), second: math.degrees(data.motion.sigma_u[1])}
    left = {}
    if data.meas_sigma is not None:
        left["sigma_bearing_deg"] = "the log gives each bearing its own sigma: one tuned value would replace them"
    else:
        values["sigma_bearing_deg"] = math.degrees(data.sigma_bearing)
    return "ekf", values, left


def make_data(cfg: OmniConfig, run: int) -> OmniData:
    """The run's dataset, its grid set (with ``from_images``, the image stage's bearings)."""
    return with_stage(cfg, run)[0]


def with_stage(cfg: OmniConfig, run: int, record: bool = False) -> tuple[OmniData, object | None]:
    """The run's dataset and the image stage, if any (``record``: it keeps a frame a second)."""
    stage = None
    if cfg.scenario == "mrclam":
        from workbench.experiments.omni import real

        data = real.load(cfg)
    elif cfg.scenario == "log":
        from workbench.experiments.omni import log

        data = log.read(cfg.data, cfg)
    else:
        data = simulate(cfg, np.random.default_rng([cfg.seed, run]))
    if cfg.from_images:
        from workbench.experiments.omni import images

        cam = images.MirrorCamera(size=cfg.image_size, noise=cfg.image_noise)
        stage = images.run_stage(data, cam, cfg, np.random.default_rng([cfg.seed, run, 1]),
                                 keep_every=int(round(cfg.bearing_rate)) if record else 0, bad_frames=cfg.bad_frames)
        data = stage.data
    data.grid = keyframe_steps(data, cfg.keyframe_every)
    return data, stage


def run_once(cfg: OmniConfig, run: int, estimators: list[Estimator], record: bool = False,
             threads: int = 1) -> RunResult:
    """One run; ``record`` keeps what the recording draws (the image stage's frames,
    initialisation attempts, the graph's map through time)."""
    from workbench.experiments.omni.experiment import EXPERIMENT

    data, stage = with_stage(cfg, run, record)
    return contract.run_estimators(EXPERIMENT, cfg, run, estimators, data, record, threads, images=stage)


def write_log(data: OmniData, folder, force: bool = False) -> list:
    """A dataset in the open log format (``--export-data``; :mod:`.log`)."""
    from workbench.experiments.omni import log

    return log.write(data, folder, force)
