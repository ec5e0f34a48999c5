"""Synthetic omni logs with the faults real logs carry, in the open log format (:mod:`.log`):
a car's drive through a field of trees, odometry as pose increments with each step's covariance,
bearings with landmark ids, the truth and the landmark survey.

The faults, each a setting of :func:`write`:

* ``odometry_stated``, ``bearing_stated``: the stated sigmas over the true ones (0.1: a log whose
  covariances are 10x too small, as a real car log's were);
* ``misread``: the share of bearings given another landmark's id (a misread barcode, a wrong
  association);
* ``student_t``: the bearing noise's Student-t degrees of freedom (heavy tails; 0: Gaussian);
* ``blind``: seconds with no bearing, every ``blind_every`` seconds (a camera's dropout);
* ``swap``: two landmark ids whose surveyed places are exchanged (a survey with swapped ids).

``odometry = "unicycle"`` writes the same drive's odometry as speed and yaw rate per step instead
(``SIGMA_V``, ``SIGMA_W`` white per step, the manifest's sigmas stated x ``odometry_stated``).

What the diagnosis (:mod:`workbench.metrics.diagnosis`) must say of each is measured on them
(``tests/test_diagnosis.py``, ``benchmarks/diagnosis_agreement.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.io import logs as logfiles

SIGMA_BEARING = math.radians(1.0)
SIGMA_V = 0.1                    # m/s, a unicycle log's speed noise per step
SIGMA_W = math.radians(2.0)      # rad/s, its yaw rate's


@dataclass(frozen=True)
class Faults:
    """The drive and its faults (see the module's text)."""

    poses: int = 3000
    dt: float = 0.2
    landmarks: int = 150
    area: float = 220.0
    speed: float = 2.0
    max_range: float = 30.0
    bearing_every: int = 5
    odometry_stated: float = 1.0
    bearing_stated: float = 1.0
    misread: float = 0.0
    student_t: float = 0.0
    blind: float = 0.0
    blind_every: float = 200.0
    swap: tuple[int, int] | None = None
    seed: int = 0
    odometry: str = "increments"   # or "unicycle"


def simulate(f: Faults) -> dict:
    """The drive: true poses, true and noisy increments with their true covariances, the
    bearings (time, bearing, landmark index, true landmark), the landmarks."""
    rng = np.random.default_rng(f.seed)
    half = f.area / 2
    lms = rng.uniform(-half, half, (f.landmarks, 2))
    poses = np.zeros((f.poses, 3))
    w = 0.0
    for k in range(1, f.poses):
        x, y, phi = poses[k - 1]
        to_centre = math.atan2(-y, -x) - phi
        to_centre = (to_centre + math.pi) % (2 * math.pi) - math.pi
        pull = 0.3 * to_centre if math.hypot(x, y) > 0.7 * half else 0.0
        w = 0.95 * w + 0.05 * rng.normal(0.0, 0.3) + 0.05 * pull
        d = f.speed * f.dt
        poses[k] = x + d * math.cos(phi), y + d * math.sin(phi), phi + w * f.dt
    c, s = np.cos(poses[:-1, 2]), np.sin(poses[:-1, 2])
    dxy = poses[1:, :2] - poses[:-1, :2]
    inc = np.column_stack([c * dxy[:, 0] + s * dxy[:, 1], -s * dxy[:, 0] + c * dxy[:, 1],
                           np.diff(np.unwrap(poses[:, 2]))])
    sig = np.column_stack([0.02 * np.abs(inc[:, 0]) + 0.005, np.full(len(inc), 0.005),
                           np.full(len(inc), math.radians(0.3))])
    noisy = inc + rng.normal(size=inc.shape) * sig
    rates = np.column_stack([np.full(len(inc), f.speed), np.diff(np.unwrap(poses[:, 2])) / f.dt])
    rates = rates + rng.normal(size=rates.shape) * np.array([SIGMA_V, SIGMA_W])
    t_b, b, lm_of, true_lm = [], [], [], []
    blind = np.zeros(f.poses, bool)
    if f.blind > 0:
        t = np.arange(f.poses) * f.dt
        blind = (t % f.blind_every) >= f.blind_every - f.blind
    for k in range(0, f.poses, f.bearing_every):
        if blind[k]:
            continue
        d = lms - poses[k, :2]
        near = np.flatnonzero(np.hypot(d[:, 0], d[:, 1]) < f.max_range)
        for j in near:
            noise = (rng.standard_t(f.student_t) * math.sqrt((f.student_t - 2) / f.student_t) if f.student_t > 2
                     else rng.standard_t(f.student_t) if f.student_t > 0 else rng.normal())
            z = math.atan2(d[j, 1], d[j, 0]) - poses[k, 2] + SIGMA_BEARING * noise
            said = j
            if f.misread > 0 and rng.random() < f.misread:
                said = int(rng.choice(np.delete(np.arange(f.landmarks), j)))
            t_b.append(k * f.dt)
            b.append((z + math.pi) % (2 * math.pi) - math.pi)
            lm_of.append(said)
            true_lm.append(j)
    return {"poses": poses, "increments": noisy, "sigmas": sig, "rates": rates, "landmarks": lms, "t_b": np.array(t_b),
            "bearings": np.array(b), "ids": np.array(lm_of, int), "true_ids": np.array(true_lm, int)}


def write(folder: Path, f: Faults = Faults(), force: bool = False) -> list[Path]:
    """The drive with its faults as an omni log folder (:mod:`.log`'s format); the truth and
    the survey (with ``swap`` applied) included."""
    sim = simulate(f)
    t = np.arange(f.poses) * f.dt
    stated = sim["sigmas"] * f.odometry_stated
    var = np.column_stack([stated**2, np.zeros((len(stated), 3))])
    rows = np.column_stack([t, np.vstack([sim["increments"], np.zeros(3)]), np.vstack([var, np.zeros(6)])])
    survey = sim["landmarks"].copy()
    if f.swap is not None:
        a, b = f.swap
        survey[[a, b]] = survey[[b, a]]
    odometry = (("t_s", "dx_m", "dy_m", "dphi_rad", "var_dx_m2", "var_dy_m2", "var_dphi_rad2", "cov_dx_dy_m2",
                 "cov_dx_dphi_mrad", "cov_dy_dphi_mrad"), rows)
    motion = {"motion": "increments", "noise_per_second": False}
    if f.odometry == "unicycle":
        odometry = (("t_s", "v_mps", "w_radps"), np.column_stack([t, np.vstack([sim["rates"], np.zeros(2)])]))
        motion = {"motion": "unicycle", "noise_per_second": False, "sigma_v_mps": SIGMA_V * f.odometry_stated,
                  "sigma_w_radps": SIGMA_W * f.odometry_stated}
    files = {
        "odometry.csv": odometry,
        "bearings.csv": (("t_s", "bearing_rad", "landmark_id"), np.column_stack([sim["t_b"], sim["bearings"],
                                                                               sim["ids"]])),
        "truth.csv": (("t_s", "x_m", "y_m", "phi_rad"), np.column_stack([t, sim["poses"]])),
        "landmarks.csv": (("landmark_id", "x_m", "y_m"), np.column_stack([np.arange(f.landmarks), survey])),
    }
    meta = {"format": 1, "experiment": "omni", **motion,
            "sigma_bearing_rad": SIGMA_BEARING * f.bearing_stated, "commands": "held",
            "start": sim["poses"][0].tolist(), "start_cov": (np.diag([0.01, 0.01, math.radians(0.5)]) ** 2).tolist(),
            "max_range_m": f.max_range, "label": f"synthetic drive with faults (seed {f.seed})"}
    return logfiles.write(Path(folder), files, meta, force)


def turned(poses: np.ndarray, how: str) -> np.ndarray:
    """A wrong start for a smoother (the faults' grid, issue 34): the trajectory ``poses (E, 3)``
    mirrored about its first pose's heading (``"mirrored"``) or rotated 90 deg about its first
    pose (``"rotated"``), the first pose kept."""
    x0, y0, h = poses[0]
    c, s = math.cos(h), math.sin(h)
    rel = poses[:, :2] - [x0, y0]
    u, v = rel @ [c, s], rel @ [-s, c]  # along and across the start's heading
    if how == "mirrored":
        v, phi = -v, 2 * h - poses[:, 2]
    else:
        u, v, phi = -v, u, poses[:, 2] + math.pi / 2
    out = np.column_stack([x0 + c * u - s * v, y0 + s * u + c * v, phi])
    out[0] = poses[0]
    return out
