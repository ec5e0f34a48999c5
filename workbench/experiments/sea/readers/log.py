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
                    ``vx_mps``, ``vy_mps``; one row per step, the steps uniform
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

import json
import math
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, require
from workbench.experiments.sea import geometry
from workbench.experiments.sea.readers import csvfile
from workbench.experiments.sea.scenario import SeaData

FORMAT = 1
MANIFEST = ("height_m", "sigma_azimuth_rad", "sigma_elevation_rad", "sigma_observer_m", "sigma_acc_mps2")
STEP_TOLERANCE = 1e-6
"""How far (a fraction of the step) a time may be from the uniform grid of the steps."""


def write(data: SeaData, folder: Path, force: bool = False) -> list[Path]:
    """The dataset as a log folder (CSV, every number as Python writes it back exactly)."""
    from workbench.recording.stream import check_plain_output, write_text_atomic

    folder = Path(folder)
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
    paths = [folder / name for name in (*files, "manifest.json")]
    for p in paths:
        check_plain_output(p, force, "log file")
    for name, (columns, rows) in files.items():
        text = ",".join(columns) + "\n" + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in rows)
        write_text_atomic(folder / name, text, force)
    write_text_atomic(folder / "manifest.json", json.dumps(manifest, indent=1) + "\n", force)
    return paths


def read(folder: Path) -> SeaData:
    """A log folder as a :class:`SeaData` (truth NaN where the log has none)."""
    folder = Path(folder).expanduser()
    require(folder.is_dir(), f"--data {folder}: not a log folder (it needs manifest.json, observer.csv, angles.csv)")
    repairs: dict[str, int] = {}
    m = _manifest(folder / "manifest.json")
    obs = _table(folder, "observer", ("t_s", "course_rad"), repairs, optional=("x_m", "y_m", "lat_deg", "lon_deg",
                                                                                 "vx_mps", "vy_mps"))
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
    velocity = (np.column_stack([obs["vx_mps"], obs["vy_mps"]]) if "vx_mps" in obs and "vy_mps" in obs
                else np.gradient(observer, dt, axis=0))
    ang = _table(folder, "angles", ("t_s", "azimuth_rad", "elevation_rad"), repairs)
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
        tr = _table(folder, "truth", ("t_s", "x_m", "y_m", "vx_mps", "vy_mps"), repairs,
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
                   repairs=repairs)


def _manifest(path: Path) -> dict:
    if not path.is_file():
        raise WorkbenchError(f"{path}: missing (the log's manifest: {', '.join(MANIFEST)})")
    try:
        m = json.loads(path.read_text(encoding="utf-8-sig"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise WorkbenchError(f"{path}: not JSON ({str(exc).splitlines()[0]})") from None
    require(isinstance(m, dict), f"{path}: not a JSON object")
    for key in MANIFEST:
        v = m.get(key)
        require(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0,
                f"{path}: {key} must be a non-negative number, got {v!r}")
    require(m["height_m"] > 0 and m["sigma_azimuth_rad"] > 0 and m["sigma_elevation_rad"] > 0,
            f"{path}: height_m and the angles' sigmas must be positive")
    dt = m.get("dt_s")
    require(dt is None or (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0),
            f"{path}: dt_s must be a positive number, got {dt!r}")
    return m


def _table(folder: Path, name: str, columns: tuple[str, ...], repairs: dict, optional: tuple[str, ...] = ()) -> dict:
    """A CSV (or Parquet) table's columns as float arrays, in time order (repairs counted), with
    each row's line in the file (``lines``)."""
    parquet, path = folder / f"{name}.parquet", folder / f"{name}.csv"
    if parquet.exists() and not path.exists():
        return _parquet(parquet, columns, optional)
    if not path.is_file():
        raise WorkbenchError(f"{path}: missing")
    import csv

    with open(path, newline="", encoding="utf-8-sig") as fh:
        header = [h.strip() for h in next(csv.reader(fh), [])]
    present = [c for c in optional if c in header]

    def parse(record: dict[str, str]) -> tuple:
        out = []
        for c in (*columns, *present):
            try:
                out.append(csvfile.finite(record[c]))
            except ValueError as exc:
                raise ValueError(f"column {c}: {exc}") from None
        return tuple(out)

    rows, lines = csvfile.read_rows(path, columns, parse, name, repairs)
    table = np.array(rows, float).reshape(len(rows), -1)
    order = csvfile.in_order(path, table[:, 0], lines, 1.0, name, repairs)
    table, lines = table[order], np.asarray(lines)[order]
    keep = csvfile.last_of_repeats(table[:, 0])
    if not keep.all():
        csvfile.count(repairs, f"{name}_repeated_stamps", int((~keep).sum()))
        csvfile.say(path, f"{int((~keep).sum())} repeated time stamp(s): the last row of each kept")
    out = {c: table[keep, i] for i, c in enumerate((*columns, *present))}
    out["lines"] = lines[keep]
    return out


def _parquet(path: Path, columns: tuple[str, ...], optional: tuple[str, ...]) -> dict:
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    missing = [c for c in columns if c not in table.column_names]
    require(not missing, f"{path}: missing column(s) {', '.join(missing)} (its columns: "
                         f"{', '.join(table.column_names)[:120]})")
    require(table.num_rows > 0, f"{path}: no rows")
    out = {}
    for c in (*columns, *[c for c in optional if c in table.column_names]):
        v = np.asarray(table[c].to_numpy(zero_copy_only=False), float)
        if not np.isfinite(v).all():
            raise WorkbenchError(f"{path}, row {int(np.flatnonzero(~np.isfinite(v))[0]) + 1}, column {c}: "
                                 "not a finite number")
        out[c] = v
    back = np.flatnonzero(np.diff(out["t_s"]) <= 0)
    if back.size:
        raise WorkbenchError(f"{path}, row {int(back[0]) + 2}, column t_s: times out of order or repeated")
    out["lines"] = np.arange(2, table.num_rows + 2)
    return out


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
