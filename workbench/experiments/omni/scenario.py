"""The dataset every omni estimator reads, and the paper's simulation that makes one.

A dataset is odometry (a control per step), bearings (step, landmark, angle) and, where
known, the truth. The same :class:`OmniData` comes from the simulation here and from the
real robots (:mod:`workbench.experiments.omni.readers.real`), so every estimator runs on both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.estimation.angles import wrap
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.motion import Motion


@dataclass
class OmniData:
    """Odometry, bearings and truth of one run: the dataset every omni estimator reads.

    World frame x, y in metres, headings in radians (counter-clockwise from x). ``t (K,)`` s;
    ``controls[k]`` acts from ``t[k]`` to ``t[k+1]`` through ``motion`` (the paper's bicycle
    (V, steering) or MRCLAM's unicycle (v, w)); ``start`` / ``start_cov`` the known start pose
    ``(x, y, phi)``. Bearing ``i`` (rad, from the heading, wrapped) is taken at pose
    ``meas_step[i]`` of landmark index ``meas_lm[i]`` (a row of ``landmarks``), with noise
    ``sigma_bearing`` (rad), or its own ``meas_sigma[i]`` where a log gives each one
    (:meth:`bearing_sigma`; ``sigma_bearing`` is then their RMS, for what takes one).
    ``truth (K, 3)`` and ``landmarks (N, 2)`` are for evaluation: an estimator must not read them. ``grid`` are
    the steps every estimator is scored at (the bearing epochs, and one at least every
    ``keyframe_every`` seconds). ``control_var (K, 2)``, where the log leaves a step's control
    uncertain beyond ``motion``'s noise (a gap in a real log, :mod:`.real`), is that step's own
    extra variance of its (mean) control; ``None``: none. Estimators read a stretch of odometry with
    :meth:`odometry`.
    """

    t: np.ndarray
    controls: np.ndarray
    motion: Motion
    start: np.ndarray
    start_cov: np.ndarray
    truth: np.ndarray
    meas_step: np.ndarray
    meas_lm: np.ndarray
    meas_bearing: np.ndarray
    sigma_bearing: float
    landmark_ids: np.ndarray
    landmarks: np.ndarray
    fov: float
    max_range: float
    label: str
    walls: np.ndarray | None = None
    grid: np.ndarray | None = None
    repairs: dict | None = None   # what a real log needed to be read (mrclam.MrclamLog.repairs), and its drops
    control_var: np.ndarray | None = None
    truth_sigma: np.ndarray | None = None  # (K,) the truth's position sigma per axis, m (a GPS fix's); None: exact
    meas_sigma: np.ndarray | None = None   # each bearing's own sigma, rad (a log's); None: sigma_bearing for all

    def bearing_sigma(self, idx: np.ndarray | None = None) -> np.ndarray:
        """The sigma of bearings ``idx`` (all: None), rad: each one's own where the log gives them."""
        idx = np.arange(len(self.meas_bearing)) if idx is None else np.asarray(idx, int)
        return (np.asarray(self.meas_sigma, float)[idx] if self.meas_sigma is not None
                else np.full(len(idx), float(self.sigma_bearing)))

    @property
    def dt(self) -> np.ndarray:
        return np.diff(self.t)

    def odometry(self, a: int = 0, b: int | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Steps ``a`` to ``b``'s controls, durations and extra control variances (or ``None``),
        the arguments of :meth:`.motion.Motion.propagate` after the start."""
        b = self.steps if b is None else b
        var = None if self.control_var is None else self.control_var[a:b]
        return self.controls[a:b], np.diff(self.t[a:b + 1]), var

    @property
    def steps(self) -> int:
        return len(self.controls)

    def epochs(self) -> list[tuple[int, np.ndarray]]:
        """``(step, measurement indices)`` for every step with bearings, in time order."""
        if len(self.meas_step) == 0:
            return []
        cuts = np.flatnonzero(np.diff(self.meas_step)) + 1
        groups = np.split(np.arange(len(self.meas_step)), cuts)
        return [(int(self.meas_step[g[0]]), g) for g in groups]


def keyframe_steps(data: OmniData, every: float) -> np.ndarray:
    """The scoring grid (and the graph's keyframes): every bearing epoch, the start, and a step
    at least every ``every`` seconds, so a stretch without landmarks still has poses."""
    marks = {s for s, _ in data.epochs()}
    marks.add(0)
    t = data.t
    last = 0.0
    for k in range(len(t)):
        if k in marks:
            last = t[k]
        elif t[k] - last >= every:
            marks.add(k)
            last = t[k]
    return np.array(sorted(marks), int)


def world(cfg: OmniConfig) -> np.ndarray:
    """Landmarks ``(N, 2)``: ``wall_lines`` spread round the walls (corners first), then
    ``pillars`` on a ring inside the route."""
    side = cfg.room
    lines = []
    if cfg.wall_lines:
        perimeter = 4 * side
        for s in np.arange(cfg.wall_lines) * perimeter / cfg.wall_lines:
            edge, along = divmod(s, side)
            lines.append([(along, 0.0), (side, along), (side - along, side), (0.0, side - along)][int(edge)])
    centre = side / 2
    radius = centre - cfg.inset - 0.45 * (centre - cfg.inset)
    for k in range(cfg.pillars):
        a = 2 * math.pi * (k + 0.5) / cfg.pillars
        lines.append((centre + radius * math.cos(a), centre + radius * math.sin(a)))
    return np.array(lines, float).reshape(-1, 2)


def route(cfg: OmniConfig) -> np.ndarray:
    """The square route's corners, closed: ``(5, 2)``, anticlockwise from the start."""
    a, b = cfg.inset, cfg.room - cfg.inset
    return np.array([(a, a), (b, a), (b, b), (a, b), (a, a)], float)


def _drive(cfg: OmniConfig, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """True poses ``(K+1, 3)`` and controls ``(K, 2)`` of a pure-pursuit driver round the route."""
    corners = route(cfg)
    seg = np.diff(corners, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    lap = cum[-1]

    def point_at(s: float) -> tuple[float, float]:
        s %= lap
        i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(seg) - 1)
        f = (s - cum[i]) / seg_len[i]
        return corners[i, 0] + f * seg[i, 0], corners[i, 1] + f * seg[i, 1]

    lookahead, max_steer = 6.0, math.radians(35.0)
    L, v, dt = cfg.wheelbase, cfg.speed, cfg.dt
    x, y, phi = corners[0, 0], corners[0, 1], math.atan2(seg[0, 1], seg[0, 0])
    poses = np.empty((steps + 1, 3))
    controls = np.empty((steps, 2))
    poses[0] = x, y, phi
    s = 0.0
    for k in range(steps):
        s += v * dt
        gx, gy = point_at(s + lookahead)
        alpha = math.atan2(gy - y, gx - x) - phi
        alpha = math.atan2(math.sin(alpha), math.cos(alpha))
        gamma = max(-max_steer, min(max_steer, math.atan2(2.0 * L * math.sin(alpha), lookahead)))
        x += dt * v * math.cos(phi + gamma)
        y += dt * v * math.sin(phi + gamma)
        phi += dt * v * math.sin(gamma) / L
        controls[k] = v, gamma
        poses[k + 1] = x, y, phi
    poses[:, 2] = wrap(poses[:, 2])
    return poses, controls


def observe(poses: np.ndarray, landmarks: np.ndarray, steps: np.ndarray, fov: float, max_range: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise-free bearings (9) of every landmark in range and field of view at ``steps``:
    ``(step, landmark, bearing)`` arrays sorted by step then landmark."""
    p = poses[steps]
    d = landmarks[None, :, :] - p[:, None, :2]
    dist = np.hypot(d[..., 0], d[..., 1])
    bearing = wrap(np.arctan2(d[..., 1], d[..., 0]) - p[:, None, 2])
    seen = (dist <= max_range) & (np.abs(bearing) <= fov / 2 + 1e-12) & (dist > 1e-6)
    si, li = np.nonzero(seen)
    return steps[si], li, bearing[si, li]


def simulate(cfg: OmniConfig, rng: np.random.Generator) -> OmniData:
    """The paper's simulation: true motion, noisy odometry (white per step), noisy bearings."""
    steps = int(round(cfg.duration / cfg.dt))
    truth, controls = _drive(cfg, steps)
    noisy = controls + rng.normal(size=controls.shape) * np.array([cfg.sigma_v, cfg.sigma_gamma])
    landmarks = world(cfg)
    every = max(1, int(round(1.0 / (cfg.bearing_rate * cfg.dt))))
    at = np.arange(every, steps + 1, every)
    ms, ml, mb = observe(truth, landmarks, at, math.radians(cfg.fov_deg), cfg.max_range)
    mb = wrap(mb + cfg.sigma_bearing * rng.normal(size=mb.shape))
    motion = Motion("bicycle", cfg.wheelbase, (cfg.sigma_v, cfg.sigma_gamma), (cfg.sigma_q,) * 3)
    a, b = 0.0, cfg.room
    walls = np.array([(a, a), (b, a), (b, b), (a, b), (a, a)], float)
    return OmniData(
        t=np.arange(steps + 1) * cfg.dt, controls=noisy, motion=motion, start=truth[0].copy(),
        start_cov=np.zeros((3, 3)), truth=truth, meas_step=ms, meas_lm=ml, meas_bearing=mb,
        sigma_bearing=cfg.sigma_bearing, landmark_ids=np.arange(len(landmarks)), landmarks=landmarks,
        fov=math.radians(cfg.fov_deg), max_range=cfg.max_range, label="paper simulation", walls=walls)
