"""Simulated scenarios: the spec's reading of the paper's Table 1, the impulse of Fig. 5,
a track loss, and a real AIS ship as the target (see :mod:`.readers.ais`).

A dataset is plain arrays; every estimator reads the same one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.estimation.angles import from_arcmin
from workbench.experiments.sea import geometry
from workbench.experiments.sea.config import SeaConfig


@dataclass
class SeaData:
    """One run's data. Unseen steps have NaN measured angles and ``seen`` False."""

    t: np.ndarray                  # (T,) s
    observer: np.ndarray           # (T, 2) true camera position, m
    observer_meas: np.ndarray      # (T, 2) measured camera position, m
    observer_velocity: np.ndarray  # (T, 2) the platform's known velocity, m/s
    course: np.ndarray             # (T,) psi, rad
    height: float                  # camera height h, m
    target: np.ndarray             # (T, 4) true x, y, vx, vy
    alpha: np.ndarray              # (T,) true azimuth, rad
    beta: np.ndarray               # (T,) true elevation, rad
    alpha_meas: np.ndarray         # (T,) measured azimuth, rad (NaN when unseen)
    beta_meas: np.ndarray          # (T,) measured elevation, rad (NaN when unseen)
    seen: np.ndarray               # (T,) bool
    disturbed: np.ndarray          # (T,) bool: impulse noise added at this step
    sigma_alpha: float             # rad
    sigma_beta: float              # rad
    sigma_observer: float          # m
    sigma_acc: float               # m/s^2
    dt: float
    label: str = ""
    impulse: np.ndarray | None = None  # (T, 2) the impulse noise added to alpha, beta (impulse scenario)
    ship: int | None = None            # ais: the ship's MMSI
    repairs: dict | None = None        # ais: what reading the real files repaired (readers.ais.AisFile.repairs, uav)
    velocity_known: bool = True        # the platform's velocity is its own (navigation), not the fixes' gradient:
                                       # its path is known up to its start (:mod:`.observer`)

    @property
    def steps(self) -> int:
        return len(self.t)

    @property
    def range(self) -> np.ndarray:
        """True horizontal range k, m."""
        return np.hypot(*(self.target[:, :2] - self.observer).T)


def simulate_target(cfg: SeaConfig, rng: np.random.Generator) -> np.ndarray:
    """Nearly-constant-velocity target (Bar-Shalom): ``x+ = x + dt v + dt^2/2 w``, ``v+ = v + dt w``."""
    T, dt = cfg.steps, cfg.dt
    w = rng.normal(0.0, cfg.sigma_acc, size=(T - 1, 2))
    vel = np.empty((T, 2))
    vel[0] = cfg.target_velocity
    vel[1:] = vel[0] + dt * np.cumsum(w, axis=0)
    pos = np.empty((T, 2))
    pos[0] = cfg.target_start
    pos[1:] = pos[0] + np.cumsum(dt * vel[:-1] + dt**2 / 2.0 * w, axis=0)
    return np.concatenate([pos, vel], axis=1)


def simulate(cfg: SeaConfig, rng: np.random.Generator, target: np.ndarray | None = None,
             observer: np.ndarray | None = None, course: np.ndarray | None = None,
             label: str = "") -> SeaData:
    """Draw one run: the paper's observer and target (unless given), then the measurements.

    The observer moves with its known constant velocity from (0, 0); its measured position
    has ``sigma_observer`` white noise per axis. The angles (1)-(2) get white noise; in
    ``impulse`` an extra N(0, impulse_sigma) for ``impulse_start <= t <= impulse_end``
    (Fig. 5); in ``track-loss`` the object is unseen for ``loss_start <= t < loss_end``.
    """
    T, dt = cfg.steps, cfg.dt
    t = np.arange(T) * dt
    if target is None:
        target = simulate_target(cfg, rng)
    if observer is None:
        velocity = np.broadcast_to(np.asarray(cfg.observer_velocity, float), (T, 2)).copy()
        observer = t[:, None] * velocity
    else:
        velocity = np.gradient(observer, dt, axis=0)
    if course is None:
        course = np.full(T, np.deg2rad(cfg.course_deg))
    alpha, beta = geometry.angles(target[:, :2], observer, course, cfg.height)
    sa, sb = from_arcmin(cfg.sigma_alpha_arcmin), from_arcmin(cfg.sigma_beta_arcmin)
    alpha_meas = alpha + rng.normal(0.0, sa, T)
    beta_meas = beta + rng.normal(0.0, sb, T)
    observer_meas = observer + rng.normal(0.0, cfg.sigma_observer, (T, 2))
    disturbed = np.zeros(T, bool)
    seen = np.ones(T, bool)
    impulse = None
    if cfg.scenario == "impulse":
        disturbed = (t >= cfg.impulse_start - 1e-9) & (t <= cfg.impulse_end + 1e-9)
        s = np.deg2rad(cfg.impulse_sigma_deg)
        impulse = np.stack([disturbed * rng.normal(0.0, s, T), disturbed * rng.normal(0.0, s, T)], axis=1)
        alpha_meas = alpha_meas + impulse[:, 0]
        beta_meas = beta_meas + impulse[:, 1]
    elif cfg.scenario == "track-loss":
        seen = ~((t >= cfg.loss_start - 1e-9) & (t < cfg.loss_end - 1e-9))
    alpha_meas = np.where(seen, alpha_meas, np.nan)
    beta_meas = np.where(seen, beta_meas, np.nan)
    return SeaData(t=t, observer=observer, observer_meas=observer_meas,
                   observer_velocity=velocity, course=np.asarray(course, float),
                   height=cfg.height, target=target, alpha=alpha, beta=beta,
                   alpha_meas=alpha_meas, beta_meas=beta_meas, seen=seen, disturbed=disturbed,
                   sigma_alpha=sa, sigma_beta=sb, sigma_observer=cfg.sigma_observer,
                   sigma_acc=cfg.sigma_acc, dt=dt, label=label or cfg.scenario, impulse=impulse)
