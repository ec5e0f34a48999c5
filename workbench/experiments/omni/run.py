"""Configure -> **data -> estimate**: run k's dataset and every estimator on it.

The dataset is simulated (seeded by ``(seed, run)``) or a real MRCLAM log (the same every
run); with ``from_images`` the round images are rendered and the estimators see the image
stage's associated bearings. Its ``grid`` (the bearing epochs, plus one step at least every
``keyframe_every`` seconds) is where every estimator is scored. Evaluation is :mod:`.evaluate`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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


def assumed(data: OmniData, cfg: OmniConfig) -> OmniData:
    """The dataset as the estimators see it (:meth:`.contract.Experiment.assumed`): the odometry's
    speed and steering (bicycle) or yaw-rate (unicycle) noise and the bearings' (each bearing's,
    where a log gave its own) where the config sets what they assume (``--assume-sigma-*``), the
    data's own elsewhere. A one-line error for a setting the data's motion model has not."""
    import dataclasses
    import math

    from workbench.errors import require

    motion, changes = data.motion, {}
    turn = {"bicycle": ("assume_sigma_gamma_deg", "--assume-sigma-gamma"),
            "unicycle": ("assume_sigma_w_deg", "--assume-sigma-w")}
    for name, flag in (("assume_sigma_gamma_deg", "--assume-sigma-gamma"), ("assume_sigma_w_deg", "--assume-sigma-w"),
                       ("assume_sigma_v", "--assume-sigma-v")):
        if getattr(cfg, name) is not None:
            ok = name == "assume_sigma_v" and motion.model in turn or turn.get(motion.model, ("",))[0] == name
            require(ok, f"{flag}: this data's odometry is {motion.model}, which has no such noise")
    sigma_u = list(motion.sigma_u)
    if cfg.assume_sigma_v is not None:
        sigma_u[0] = float(cfg.assume_sigma_v)
    turning = getattr(cfg, turn[motion.model][0]) if motion.model in turn else None
    if turning is not None:
        sigma_u[1] = math.radians(turning)
    if tuple(sigma_u) != tuple(motion.sigma_u):
        changes["motion"] = dataclasses.replace(motion, sigma_u=tuple(sigma_u))
    if cfg.assume_sigma_bearing_deg is not None:
        changes.update(sigma_bearing=math.radians(cfg.assume_sigma_bearing_deg), meas_sigma=None)
    return dataclasses.replace(data, **changes) if changes else data


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
