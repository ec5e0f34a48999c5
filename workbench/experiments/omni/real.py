"""The real robots as an :class:`OmniData`: MRCLAM odometry (unicycle), bearings, Vicon truth.

Readings taken: the poses are the odometry's time stamps (about 67 Hz) and a bearing is
attached to the nearest one (at most half a step, under 8 ms, away); ``controls[k]`` is the
``(v, w)`` reported at ``t[k]``, held until ``t[k+1]``. The start pose comes from the
ground truth (as SLAM needs a gauge), with a small covariance for the Vicon's error. The
camera's field of view is that of the measured bearings (about +-33 deg).

The odometry's noise: with ``noise_per_second`` the sigmas are densities (the log's steps
are irregular, 0.01 s mostly, up to 1 s; see :mod:`workbench.experiments.omni.motion`). The
values the ``mrclam`` scenario uses, ``sigma_w`` = 2 deg/s/sqrt(Hz) and ``sigma_v`` = 0.02
m/s/sqrt(Hz), follow the data README's description (the heading of dead reckoning drifts
about 30 deg within a couple of minutes, a random walk of 2-3 deg per square-root second;
the speed is over-reported by several per cent of 7 cm/s). No scale or lag correction is
applied to the odometry: the README's 5-18 % over-reported turning and 0.16 s lead were
measured against the Vicon, which the estimators must not use, and over the stretches that
matter here (up to 20-40 s between sightings) the heading error grows like a random walk,
not like a scale error.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from workbench.errors import require
from workbench.experiments.omni import mrclam
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.motion import Motion
from workbench.experiments.omni.scenario import OmniData
from workbench.paths import data_root

START_SIGMA = (0.01, 0.01, math.radians(0.5))


def folder(cfg: OmniConfig) -> Path:
    return Path(cfg.data).expanduser() if cfg.data is not None else data_root() / "mrclam6"


def load(cfg: OmniConfig) -> OmniData:
    """Robot ``cfg.robot``'s log, from ``start_time`` to ``end_time`` seconds into it."""
    where = folder(cfg)
    full = mrclam.load(where, cfg.robot)
    t_start = full.t0 + cfg.start_time if cfg.start_time is not None else None
    t_end = full.t0 + cfg.end_time if cfg.end_time is not None else None
    log = mrclam.load(where, cfg.robot, t_start, t_end) if (t_start is not None or t_end is not None) else full
    require(len(log.odom_t) >= 2, f"robot {cfg.robot}: fewer than two odometry rows in the chosen stretch")
    t = log.odom_t - log.t0
    controls = np.stack([log.odom_v, log.odom_w], axis=1)[:-1]
    step = np.clip(np.searchsorted(log.odom_t, log.meas_t), 1, len(t) - 1)
    nearer_before = (log.meas_t - log.odom_t[step - 1]) < (log.odom_t[step] - log.meas_t)
    step = np.where(nearer_before, step - 1, step)
    ids, positions = log.landmark_array()
    index = {int(s): i for i, s in enumerate(ids)}
    meas_lm = np.array([index[int(s)] for s in log.meas_landmark], int)
    order = np.argsort(step, kind="stable")
    truth = log.truth_at(log.odom_t)
    start = log.truth_at(np.array([log.odom_t[0]]))[0]
    require(np.isfinite(start).all(), f"robot {cfg.robot}: no ground truth at the start of the stretch")
    motion = Motion("unicycle", 0.0, (cfg.sigma_v, math.radians(cfg.sigma_w_deg)), (cfg.sigma_q,) * 3,
                    per_second=cfg.noise_per_second)
    fov = 2.0 * float(np.max(np.abs(log.meas_bearing))) if len(log.meas_bearing) else math.radians(cfg.fov_deg)
    return OmniData(
        t=t, controls=controls, motion=motion, start=start, start_cov=np.diag(np.square(START_SIGMA)),
        truth=truth, meas_step=step[order], meas_lm=meas_lm[order], meas_bearing=log.meas_bearing[order],
        sigma_bearing=cfg.sigma_bearing, landmark_ids=ids, landmarks=positions, fov=fov,
        max_range=cfg.max_range, label=f"MRCLAM {where.name} robot {cfg.robot}",
        repairs={**log.repairs, **{f"dropped_{k}": v for k, v in log.dropped.items() if v}})
