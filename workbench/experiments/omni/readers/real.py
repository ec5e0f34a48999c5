"""The real robots as an :class:`OmniData`: MRCLAM odometry (unicycle), bearings, Vicon truth.

Readings taken: the poses are the odometry's time stamps (about 67 Hz) and a bearing is
attached to the nearest one (at most half a step, under 8 ms, away). The log's rows are
velocity *commands* (MRCLAM's documentation), and a command takes over at a time the log does
not say: ``controls[k]`` is the mean of the ``(v, w)`` logged at ``t[k]`` and ``t[k+1]``, with
the variance of a switch at an unknown time between them (:func:`between`; ``--odometry-between
hold`` holds the earlier command instead, the reading before). Across the log's gaps (up to
0.9 s) this matters: on robot 4, whose 504 gaps over 0.1 s carry a quarter of its distance,
holding the command before a gap makes the distance in the gaps 36 % longer than the Vicon's,
the switch's mean 3 % (the other robots: +8 to +25 % against -13 to +2 %); the heading's
error over a gap, over its predicted sigma, squared, averages 0.6-1.5 on the five robots with
the switch's variance (0.6-2.5 holding). The start pose comes from the ground truth (as SLAM
needs a gauge), with a small covariance for the Vicon's error; a log without its truth starts at
the origin (the map is then scored, where a landmark file is given, after the best rigid
alignment: :mod:`.metrics`). The camera's field of view is
that of the measured bearings (about +-33 deg).

The odometry's noise: with ``noise_per_second`` the sigmas are densities (the log's steps
are irregular, 0.01 s mostly, up to 1 s; see :mod:`workbench.experiments.omni.motion`). The
values the ``mrclam`` scenario uses, ``sigma_w`` = 2 deg/s/sqrt(Hz) and ``sigma_v`` = 0.02
m/s/sqrt(Hz), follow the data README's description (the heading of dead reckoning drifts
about 30 deg within a couple of minutes, a random walk of 2-3 deg per square-root second;
the speed is over-reported by several per cent of 7 cm/s). No scale or lag correction is
applied to the odometry: the README's 5-18 % over-reported turning and 0.16 s lead were
measured against the Vicon, which the estimators must not use, and over the stretches that
matter here (up to 20-40 s between sightings) the heading error grows like a random walk,
not like a scale error. The bearings do measure both (a tracked landmark's bearing turns at
minus the turn rate, to first order): 0.22-0.32 s and 6-21 % on dataset 6's robots, against
the Vicon's 0.18-0.22 s and 6-15 %; but correcting either moved some robots' smoother from
0.14 to 0.37 m or into a wrong minimum (the README's MRCLAM section), so neither is applied.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from workbench.errors import require
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.motion import Motion
from workbench.experiments.omni.readers import mrclam
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
    controls, control_var = between(np.stack([log.odom_v, log.odom_w], axis=1), cfg.odometry_between)
    step = np.clip(np.searchsorted(log.odom_t, log.meas_t), 1, len(t) - 1)
    nearer_before = (log.meas_t - log.odom_t[step - 1]) < (log.odom_t[step] - log.meas_t)
    step = np.where(nearer_before, step - 1, step)
    ids, positions = log.landmark_array()
    index = {int(s): i for i, s in enumerate(ids)}
    meas_lm = np.array([index[int(s)] for s in log.meas_landmark], int)
    order = np.argsort(step, kind="stable")
    truth = log.truth_at(log.odom_t)
    start = log.truth_at(np.array([log.odom_t[0]]))[0]
    if len(log.truth_t) == 0:  # no truth: the first pose is the origin (a researcher's own log)
        start = np.zeros(3)
    require(np.isfinite(start).all(), f"robot {cfg.robot}: no ground truth at the start of the stretch")
    motion = Motion("unicycle", 0.0, (cfg.sigma_v, math.radians(cfg.sigma_w_deg)), (cfg.sigma_q,) * 3,
                    per_second=cfg.noise_per_second)
    fov = 2.0 * float(np.max(np.abs(log.meas_bearing))) if len(log.meas_bearing) else math.radians(cfg.fov_deg)
    return OmniData(
        t=t, controls=controls, motion=motion, start=start, start_cov=np.diag(np.square(START_SIGMA)),
        truth=truth, meas_step=step[order], meas_lm=meas_lm[order], meas_bearing=log.meas_bearing[order],
        sigma_bearing=cfg.sigma_bearing, landmark_ids=ids, landmarks=positions, fov=fov,
        max_range=cfg.max_range, label=f"MRCLAM {where.name} robot {cfg.robot}",
        repairs={**log.repairs, **{f"dropped_{k}": v for k, v in log.dropped.items() if v}},
        control_var=control_var)


def between(commands: np.ndarray, how: str = "switch") -> tuple[np.ndarray, np.ndarray | None]:
    """Each step's control and its extra variance from the logged commands ``(K+1, 2)``.

    ``switch``: the robot runs ``u[k]`` until the next command ``u[k+1]`` takes over at a time
    unknown within the step, uniform over it; the step's mean control is then
    ``(u[k] + u[k+1]) / 2`` with variance ``(u[k+1] - u[k])^2 / 12``. ``hold``: ``u[k]`` over the
    whole step, no extra variance. On rows 10 ms apart the two agree; they part across the log's
    gaps (robot 4 of MRCLAM 6: 504 rows over 0.1 s apart, up to 0.9 s, a quarter of its
    distance), where a command usually changes (to a stop, mostly) and ``hold`` runs the old
    one to the end.
    """
    if how == "hold":
        return commands[:-1].copy(), None
    jump = np.diff(commands, axis=0)
    return 0.5 * (commands[:-1] + commands[1:]), jump * jump / 12.0
