"""A sea log of your own, in an open, tidy format (``docs/log-formats.md``): what ``--scenario log
--data DIR`` reads and ``--export-data DIR`` writes (run 0's dataset of any scenario).

A folder of CSV files (or Parquet files of the same names and columns), a row per time, the
columns named with their units; the local frame is the sea's: x east, y north, metres:

==================  ==========================================================================
``manifest.json``   ``height_m`` (the camera's height over the sea), ``sigma_azimuth_rad``,
                    ``sigma_elevation_rad`` (the angles' noise), ``sigma_observer_m`` (the camera
                    position's noise per axis), ``sigma_acc_mps2`` (the object's acceleration
                    noise the estimators assume), optionally ``dt_s`` (the step; else the times'),
                    ``label``
``observer.csv``    ``t_s``, ``x_m``, ``y_m`` (the measured camera position) or ``lat_deg``,
                    ``lon_deg`` (then the local frame is centred on the first fix), ``course_rad``
                    (the platform's course psi, from which the azimuth is measured), optionally
                    ``vx_mps``, ``vy_mps`` (its own velocity: without it, the fixes' gradient,
                    and the estimators fold each fix in, :mod:`.observer`); one row per step,
                    the steps uniform
``angles.csv``      ``t_s``, ``azimuth_rad`` (from the course, in (-pi, pi]), ``elevation_rad``
                    (below the horizon): the measurements; a step without a row is unseen
``truth.csv``       optional: ``t_s``, ``x_m``, ``y_m``, ``vx_mps``, ``vy_mps`` (the object), and
                    optionally ``observer_x_m``, ``observer_y_m`` (the camera's true position);
                    the times it covers are scored, the others not
==================  ==========================================================================

Quirks real logs have are repaired with a count (:mod:`.csvfile`: a last line cut short, rows out
of time order, repeated stamps); what cannot be read unambiguously is one line naming the file,
the line and the column, and nothing is written.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, require
from workbench.experiments.sea import geometry
from workbench.experiments.sea.scenario import SeaData
from workbench.io import csvfiles as csvfile
from workbench.io import logs as logfiles

FORMAT = 1
MANIFEST = ("height_m", "sigma_azimuth_rad", "sigma_elevation_rad", "sigma_observer_m", "sigma_acc_mps2")
STEP_TOLERANCE = 1e-6
"""How far (a fraction of the step) a time may be from the uniform grid of the steps."""


def write(data: SeaData, folder: Path, force: bool = False) -> list[Path]:
    """The dataset as a log folder (CSV, every number as Python writes it back exactly)."""
    truth = np.isfinite(data.target).all(axis=1)
    files = {
        "observer.csv": (("t_s", "x_m", "y_m", "vx_mps", "vy_mps", "course_rad"),
                         np.column_stack([data.t, data.observer_meas, data.observer_velocity, data.course])),
        "angles.csv": (("t_s", "azimuth_rad", "elevation_rad"),
                       np.column_stack([data.t, data.alpha_meas, data.beta_meas])[data.seen]),
    }
    if truth.any():
        files["truth.csv"] = (("t_s", "x_m", "y_m", "vx_mps", "vy_mps", "observer_x_m", "observer_y_m"),
                              np.column_stack([data.t, data.target, data.observer])[truth])
    manifest = {"format": FORMAT, "experiment": "sea", "height_m": data.height, "sigma_azimuth_rad": data.sigma_alpha,
                "sigma_elevation_rad": data.sigma_beta, "sigma_observer_m": data.sigma_observer,
                "sigma_acc_mps2": data.sigma_acc, "dt_s": data.dt, "label": data.label}
    return logfiles.write(Path(folder), files, manifest, force)


def read(folder: Path) -> SeaData:
    """A log folder as a :class:`SeaData` (truth NaN where the log has none)."""
    folder = Path(folder).expanduser()
    require(folder.is_dir(), f"--data {folder}: not a log folder (it needs manifest.json, observer.csv, angles.csv)")
    repairs: dict[str, int] = {}
    m = _manifest(folder / "manifest.json")
    obs = logfiles.table(folder, "observer", ("t_s", "course_rad"), repairs,
                         optional=("x_m", "y_m", "lat_deg", "lon_deg", "vx_mps", "vy_mps"))
    t0 = obs["t_s"][0]
    t = obs["t_s"] - t0
    require(len(t) >= 3, f"{folder / 'observer.csv'}: fewer than three rows (steps)")
    dt = float(m.get("dt_s") or np.median(np.diff(t)))
    k = np.round(t / dt)
    off = np.abs(t - k * dt) > STEP_TOLERANCE * dt
    gap = k != np.arange(len(t))
    if off.any() or gap.any():
        bad = int(np.flatnonzero(off if off.any() else gap)[0])
        why = (f"is off the uniform step of {dt:g} s" if off.any() else
               f"comes after a gap (a row a step of {dt:g} s is the format: put the unseen steps' rows in)")
        raise WorkbenchError(f"{folder / 'observer.csv'}, line {obs['lines'][bad]}, column t_s: "
                             f"{float(obs['t_s'][bad])!r} {why}")
    if "x_m" in obs and "y_m" in obs:
        observer = np.column_stack([obs["x_m"], obs["y_m"]])
    elif "lat_deg" in obs and "lon_deg" in obs:
        observer = csvfile.to_local(obs["lat_deg"], obs["lon_deg"], obs["lat_deg"][0], obs["lon_deg"][0])
    else:
        raise WorkbenchError(f"{folder / 'observer.csv'}: missing column(s) x_m, y_m (or lat_deg, lon_deg)")
    known = "vx_mps" in obs and "vy_mps" in obs  # else the fixes' own gradient: no path to hold (.observer)
    velocity = np.column_stack([obs["vx_mps"], obs["vy_mps"]]) if known else np.gradient(observer, dt, axis=0)
    ang = logfiles.table(folder, "angles", ("t_s", "azimuth_rad", "elevation_rad"), repairs)
    steps = _steps(folder / "angles.csv", ang, t0, dt, len(t))
    for col, limit in (("azimuth_rad", math.pi), ("elevation_rad", math.pi / 2)):
        out = np.abs(ang[col]) > limit
        if out.any():
            i = int(np.flatnonzero(out)[0])
            raise WorkbenchError(f"{folder / 'angles.csv'}, line {ang['lines'][i]}, column {col}: "
                                 f"{float(ang[col][i])!r} is beyond +-{limit:.4f} rad")
    alpha_meas, beta_meas = np.full(len(t), np.nan), np.full(len(t), np.nan)
    alpha_meas[steps], beta_meas[steps] = ang["azimuth_rad"], ang["elevation_rad"]
    seen = np.isfinite(alpha_meas)
    target, observer_true = np.full((len(t), 4), np.nan), observer.copy()
    if (folder / "truth.csv").exists() or (folder / "truth.parquet").exists():
        tr = logfiles.table(folder, "truth", ("t_s", "x_m", "y_m", "vx_mps", "vy_mps"), repairs,
                    optional=("observer_x_m", "observer_y_m"))
        at = _steps(folder / "truth.csv", tr, t0, dt, len(t), outside_ok=True)
        inside = at >= 0
        require(inside.any(), f"{folder / 'truth.csv'}: covers none of the run (its times are outside the "
                              f"observer's {t0:g} to {obs['t_s'][-1]:g} s)")
        target[at[inside]] = np.column_stack([tr[c] for c in ("x_m", "y_m", "vx_mps", "vy_mps")])[inside]
        if "observer_x_m" in tr and "observer_y_m" in tr:
            observer_true[at[inside]] = np.column_stack([tr["observer_x_m"], tr["observer_y_m"]])[inside]
        csvfile.count(repairs, "truth_steps_missing", int(len(t) - inside.sum()))
    course = obs["course_rad"]
    with np.errstate(invalid="ignore"):
        alpha, beta = geometry.angles(target[:, :2], observer_true, course, m["height_m"])
    return SeaData(t=t, observer=observer_true, observer_meas=observer, observer_velocity=velocity, course=course,
                   height=m["height_m"], target=target, alpha=alpha, beta=beta, alpha_meas=alpha_meas,
                   beta_meas=beta_meas, seen=seen, disturbed=np.zeros(len(t), bool), sigma_alpha=m["sigma_azimuth_rad"],
                   sigma_beta=m["sigma_elevation_rad"], sigma_observer=m["sigma_observer_m"],
                   sigma_acc=m["sigma_acc_mps2"], dt=dt, label=str(m.get("label") or f"log {folder.name}"),
                   repairs=repairs, velocity_known=known)


def _manifest(path: Path) -> dict:
    m = logfiles.manifest(path, MANIFEST, positive=("height_m", "sigma_azimuth_rad", "sigma_elevation_rad"))
    dt = m.get("dt_s")
    require(dt is None or (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0),
            f"{path}: dt_s must be a positive number, got {dt!r}")
    return m


def _steps(path: Path, table: dict, t0: float, dt: float, n: int, outside_ok: bool = False) -> np.ndarray:
    """Each row's step of the observer's uniform times (-1 outside them, where ``outside_ok``)."""
    k = np.round((table["t_s"] - t0) / dt)
    off = np.abs(table["t_s"] - t0 - k * dt) > STEP_TOLERANCE * dt
    outside = (k < 0) | (k >= n)
    bad = off & ~outside if outside_ok else off | outside
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise WorkbenchError(f"{path}, line {table['lines'][i]}, column t_s: {float(table['t_s'][i])!r} is not a "
                             "time of the observer's steps")
    return np.where(outside, -1, k).astype(int)
