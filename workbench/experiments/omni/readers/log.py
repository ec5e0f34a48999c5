"""An omni log of your own, in an open, tidy format (``docs/log-formats.md``): what ``--scenario log
--data DIR`` reads and ``--export-data DIR`` writes (run 0's dataset of any scenario).

A folder of CSV files (or Parquet files of the same names and columns, :mod:`..logfiles`); the
world frame's x, y in metres, headings in radians counter-clockwise from x:

==================  ==========================================================================
``manifest.json``   ``motion`` (``unicycle``: controls ``v_mps``, ``w_radps``; ``bicycle``, the
                    paper's (7): ``v_mps``, ``steering_rad``, with ``wheelbase_m``;
                    ``increments``: relative poses ``dx_m``, ``dy_m``, ``dphi_rad``, each row's
                    change to the next row in the body frame at the row, g2o's ``EDGE_SE2``
                    convention, with their sigmas ``sigma_dx_m``, ``sigma_dy_m``,
                    ``sigma_dphi_rad`` per step, or each row's covariance in the columns
                    ``var_dx_m2``, ``var_dy_m2``, ``var_dphi_rad2``, ``cov_dx_dy_m2``,
                    ``cov_dx_dphi_mrad``, ``cov_dy_dphi_mrad``),
                    ``sigma_bearing_rad``, the odometry's noise ``sigma_v_mps`` and
                    ``sigma_w_radps`` (or ``sigma_steering_rad``), optionally ``sigma_q`` (three
                    numbers: x, y in m, phi in rad), ``noise_per_second`` (the sigmas are densities,
                    default true), ``commands`` (``held``: a row's control acts until the next row,
                    the default; ``switch``: the next command takes over at an unknown time within
                    the step, as MRCLAM's velocity commands do), ``start`` (x, y, phi: the known
                    start pose; else the first pose is the origin), ``start_cov`` (3 x 3),
                    ``fov_rad``, ``max_range_m``, ``label``
``odometry.csv``    ``t_s`` and the two controls: a row's control acts from its time to the next
                    row's (the last row's only closes the run); optionally ``v_var_m2ps2`` and
                    ``w_var_rad2ps2`` (``steering_var_rad2``): a step's own extra variance of its
                    control (a gap in a real log)
``bearings.csv``    ``t_s``, ``bearing_rad`` (from the heading, within +-pi), optionally
                    ``landmark_id`` (an integer; without the column the association front end
                    that the image stage uses decides, :mod:`.associate`) and ``sigma_rad`` (each
                    bearing's own sigma: every estimator weighs each bearing by it); each bearing
                    is taken at the odometry row nearest its time
``truth.csv``       optional: ``t_s``, ``x_m``, ``y_m``, optionally ``phi_rad``: the robot's true
                    pose (a sparse fix, a GPS track, scores the steps it falls on), optionally
                    ``sigma_m``: the fix's noise per axis (its NEES, ``fix_nees``, adds it)
``landmarks.csv``   optional: ``landmark_id``, ``x_m``, ``y_m``: the landmark survey (the map is
                    scored against it, and after its best rigid alignment)
==================  ==========================================================================
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, require
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.motion import Motion
from workbench.experiments.omni.scenario import OmniData
from workbench.io import csvfiles as csvfile
from workbench.io import logs as logfiles

FORMAT = 1
CONTROLS = {"unicycle": (("v_mps", "w_radps"), ("v_var_m2ps2", "w_var_rad2ps2"), ("sigma_v_mps", "sigma_w_radps")),
            "bicycle": (("v_mps", "steering_rad"), ("v_var_m2ps2", "steering_var_rad2"),
                        ("sigma_v_mps", "sigma_steering_rad")),
            "increments": (("dx_m", "dy_m", "dphi_rad"),
                           ("var_dx_m2", "var_dy_m2", "var_dphi_rad2", "cov_dx_dy_m2", "cov_dx_dphi_mrad",
                            "cov_dy_dphi_mrad"),
                           ("sigma_dx_m", "sigma_dy_m", "sigma_dphi_rad"))}
"""Per motion model: the odometry's control columns, their extra variances' (for ``increments``
the covariance's upper triangle) and the manifest's sigmas."""
TRIANGLE = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
"""Where the ``increments`` covariance columns go in the 3 x 3 matrix."""
START_SIGMA = (0.01, 0.01, math.radians(0.5))
"""The start pose's sigmas where the manifest gives a start but not its covariance."""


def write(data: OmniData, folder: Path, force: bool = False) -> list[Path]:
    """The dataset as a log folder: the controls as held (the reading already applied), the
    bearings with their landmark ids, the truth and the survey where known."""
    m = data.motion
    controls, var_columns, sigmas = CONTROLS[m.model]
    width = len(controls)
    rows = np.vstack([data.controls, np.zeros((1, width))])
    columns = ("t_s", *controls)
    if data.control_var is not None:
        var = data.control_var
        if m.model == "increments":
            var = np.stack([var[:, i, j] for i, j in TRIANGLE], axis=1)
        rows = np.column_stack([rows, np.vstack([var, np.zeros((1, var.shape[1]))])])
        columns += var_columns
    files = {"odometry.csv": (columns, np.column_stack([data.t, rows])),
             "bearings.csv": (("t_s", "bearing_rad", "landmark_id"),
                              np.column_stack([data.t[data.meas_step], data.meas_bearing,
                                               data.landmark_ids[data.meas_lm]]))}
    if data.meas_sigma is not None:
        columns, rows = files["bearings.csv"]
        files["bearings.csv"] = ((*columns, "sigma_rad"), np.column_stack([rows, data.meas_sigma]))
    truth = np.isfinite(data.truth[:, :2]).all(axis=1)
    if truth.any():
        columns, rows = ("t_s", "x_m", "y_m", "phi_rad"), np.column_stack([data.t, data.truth])
        if not np.isfinite(data.truth[truth, 2]).all():  # positions alone (a fix without a heading)
            columns, rows = columns[:3], rows[:, :3]
        if data.truth_sigma is not None:
            columns, rows = (*columns, "sigma_m"), np.column_stack([rows, data.truth_sigma])
        files["truth.csv"] = (columns, rows[truth])
    surveyed = np.isfinite(data.landmarks).all(axis=1)
    if surveyed.any():
        files["landmarks.csv"] = (("landmark_id", "x_m", "y_m"),
                                  np.column_stack([data.landmark_ids, data.landmarks])[surveyed])
    meta = {"format": FORMAT, "experiment": "omni", "motion": m.model, "wheelbase_m": m.wheelbase,
            "sigma_bearing_rad": data.sigma_bearing, **dict(zip(sigmas, m.sigma_u, strict=True)),
            "sigma_q": list(m.sigma_q), "noise_per_second": m.per_second, "commands": "held",
            "start": data.start.tolist(), "start_cov": data.start_cov.tolist(), "fov_rad": data.fov,
            "max_range_m": data.max_range, "label": data.label}
    if data.walls is not None:
        meta["walls_m"] = np.asarray(data.walls).tolist()
    return logfiles.write(Path(folder), files, meta, force)


def read(folder: Path, cfg: OmniConfig) -> OmniData:
    """A log folder as an :class:`OmniData` (truth NaN where the log has none)."""
    folder = Path(folder).expanduser()
    require(folder.is_dir(), f"--data {folder}: not a log folder (it needs manifest.json, odometry.csv, "
                             "bearings.csv)")
    where = folder / "manifest.json"
    m = logfiles.manifest(where, ("sigma_bearing_rad",), positive=("sigma_bearing_rad",))
    model = m.get("motion")
    require(model in CONTROLS, f"{where}: motion must be one of {', '.join(CONTROLS)}, got {model!r}")
    controls, var_columns, sigma_keys = CONTROLS[model]
    wheelbase = logfiles.number(where, m, "wheelbase_m", positive=True) if model == "bicycle" else 0.0
    q = logfiles.numbers(where, m, "sigma_q", (3,))
    per_second = m.get("noise_per_second", model != "increments")
    require(isinstance(per_second, bool), f"{where}: noise_per_second must be true or false, got {per_second!r}")
    require(not (per_second and model == "increments"), f"{where}: noise_per_second must be false for increments "
                                                        "(each row's noise is that step's, whatever its length)")
    commands = m.get("commands", "held")
    require(commands in ("held", "switch"), f"{where}: commands must be held or switch, got {commands!r}")
    repairs: dict[str, int] = {}

    odo = logfiles.table(folder, "odometry", ("t_s", *controls), repairs, optional=var_columns)
    has_cov = model == "increments" and any(c in odo for c in var_columns)
    sigma_u = tuple(logfiles.number(where, m, k, default=0.0 if has_cov else None) for k in sigma_keys)
    require(len(odo["t_s"]) >= 2, f"{folder / 'odometry.csv'}: fewer than two rows (a step needs two times)")
    t0 = odo["t_s"][0]
    t = odo["t_s"] - t0
    u = np.column_stack([odo[c] for c in controls])
    if model == "increments":
        require(commands == "held", f"{where}: commands must be held for increments (each row is the pose change "
                                    "to the next row)")
        u, control_var = u[:-1], _covariances(folder / "odometry.csv", odo, var_columns) if has_cov else None
    elif commands == "switch":
        from workbench.experiments.omni.readers.real import between

        u, control_var = between(u, "switch")
    else:
        u = u[:-1]
        control_var = (np.column_stack([odo[c] for c in var_columns])[:-1]
                       if all(c in odo for c in var_columns) else None)

    bearings_path = folder / "bearings.csv"
    b = logfiles.table(folder, "bearings", ("t_s", "bearing_rad"), repairs, optional=("landmark_id", "sigma_rad"),
                       one_per_time=False)
    logfiles.within(bearings_path, b, "bearing_rad", math.pi)
    step = _nearest(bearings_path, b, odo["t_s"])
    sigma = logfiles.number(where, m, "sigma_bearing_rad", positive=True)
    meas_sigma = None
    if "sigma_rad" in b:
        sig = b["sigma_rad"]
        bad = np.flatnonzero(sig <= 0)
        if bad.size:
            raise WorkbenchError(f"{bearings_path}, line {b['lines'][int(bad[0])]}, column sigma_rad: "
                                 f"{float(sig[bad[0]])!r} is not a positive sigma")
        if np.ptp(sig) <= 1e-12 * sig.max():
            sigma = float(sig[0])
        else:  # each bearing its own; what takes one sigma (the association's gate) takes their RMS
            meas_sigma, sigma = sig, float(np.sqrt(np.mean(sig ** 2)))

    survey_ids, survey = np.zeros(0, np.int64), np.zeros((0, 2))
    if logfiles.has(folder, "landmarks"):
        lm = logfiles.table(folder, "landmarks", ("landmark_id", "x_m", "y_m"), repairs)
        survey_ids, survey = logfiles.integers(folder / "landmarks.csv", lm, "landmark_id"), \
            np.column_stack([lm["x_m"], lm["y_m"]])
    if "landmark_id" in b:
        ids = logfiles.integers(bearings_path, b, "landmark_id")
        landmark_ids = np.union1d(ids, survey_ids)
        meas_lm = np.searchsorted(landmark_ids, ids)
        landmarks = np.full((len(landmark_ids), 2), np.nan)
        landmarks[np.searchsorted(landmark_ids, survey_ids)] = survey
    else:
        landmark_ids, landmarks, meas_lm = np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(len(step), int)

    truth, truth_sigma = np.full((len(t), 3), np.nan), None
    if logfiles.has(folder, "truth"):
        tr = logfiles.table(folder, "truth", ("t_s", "x_m", "y_m"), repairs, optional=("phi_rad", "sigma_m"))
        at = _nearest(folder / "truth.csv", tr, odo["t_s"], outside_ok=True)
        inside = at >= 0
        require(inside.any(), f"{folder / 'truth.csv'}: covers none of the run (its times are outside the "
                              f"odometry's {t0:g} to {odo['t_s'][-1]:g} s)")
        truth[at[inside], :2] = np.column_stack([tr["x_m"], tr["y_m"]])[inside]
        if "phi_rad" in tr:
            truth[at[inside], 2] = tr["phi_rad"][inside]
        if "sigma_m" in tr:
            require(np.all(tr["sigma_m"] >= 0), f"{folder / 'truth.csv'}: sigma_m must be non-negative")
            truth_sigma = np.full(len(t), np.nan)
            truth_sigma[at[inside]] = tr["sigma_m"][inside]
        csvfile.count(repairs, "truth_steps_missing", int(len(t) - np.unique(at[inside]).size))
    start = logfiles.numbers(where, m, "start", (3,))
    start_cov = logfiles.numbers(where, m, "start_cov", (3, 3))
    if start is None:  # the first pose is the origin (a known start fixes the frame instead)
        start = np.zeros(3)
    if start_cov is None:
        start_cov = np.diag(np.square(START_SIGMA))
    order = np.argsort(step, kind="stable")
    fov = (logfiles.number(where, m, "fov_rad", positive=True) if "fov_rad" in m
           else 2.0 * float(np.max(np.abs(b["bearing_rad"]))))
    walls = logfiles.numbers(where, m, "walls_m", np.shape(m.get("walls_m"))) if "walls_m" in m else None
    data = OmniData(
        t=t, controls=u, motion=Motion(model, wheelbase, sigma_u, tuple(q) if q is not None else (0.0,) * 3,
                                       per_second=per_second),
        start=start, start_cov=start_cov, truth=truth, meas_step=step[order], meas_lm=meas_lm[order],
        meas_bearing=b["bearing_rad"][order], sigma_bearing=sigma,
        meas_sigma=None if meas_sigma is None else meas_sigma[order], landmark_ids=landmark_ids, landmarks=landmarks,
        fov=min(fov, 2.0 * math.pi), max_range=logfiles.number(where, m, "max_range_m", positive=True,
                                                               default=cfg.max_range),
        label=str(m.get("label") or f"log {folder.name}"), walls=walls, repairs=repairs, control_var=control_var,
        truth_sigma=truth_sigma)
    if "landmark_id" not in b:
        data = _associated(data, cfg)
    return data


def _covariances(path: Path, odo: dict, columns: tuple[str, ...]) -> np.ndarray:
    """Each step's covariance of its increment ``(K, 3, 3)`` from the upper triangle's columns;
    one line naming the first row whose matrix is not positive semi-definite."""
    missing = [c for c in columns if c not in odo]
    require(not missing, f"{path}: the increments' covariance needs every one of {', '.join(columns)} "
                         f"(missing: {', '.join(missing)})")
    n = len(odo["t_s"]) - 1
    cov = np.zeros((n, 3, 3))
    for c, (i, j) in zip(columns, TRIANGLE, strict=True):
        cov[:, i, j] = cov[:, j, i] = odo[c][:n]
    low = np.linalg.eigvalsh(cov).min(axis=1) < -1e-12 * np.abs(cov).max(axis=(1, 2))
    if low.any():
        k = int(np.flatnonzero(low)[0])
        raise WorkbenchError(f"{path}, line {odo['lines'][k]}, columns {', '.join(columns)}: the increment's "
                             "covariance is not positive semi-definite")
    return cov


def _associated(data: OmniData, cfg: OmniConfig) -> OmniData:
    """Bearings without landmark ids, associated by the image stage's front end (:mod:`.associate`):
    only confirmed tracks' bearings are kept; the tracks are the landmarks (no survey to score)."""
    from dataclasses import replace

    from workbench.experiments.omni.imaging.associate import associate

    assoc = associate(data, cfg)
    keep = assoc.track >= 0
    csvfile.count(data.repairs, "bearings_unassociated", int((~keep).sum()))
    return replace(data, meas_step=data.meas_step[keep], meas_lm=assoc.track[keep],
                   meas_sigma=None if data.meas_sigma is None else data.meas_sigma[keep],
                   meas_bearing=data.meas_bearing[keep], landmark_ids=np.arange(assoc.n_tracks),
                   landmarks=np.full((assoc.n_tracks, 2), np.nan))


def _nearest(path: Path, tab: dict, times: np.ndarray, outside_ok: bool = False) -> np.ndarray:
    """Each row's nearest odometry row (-1 outside the odometry's times where ``outside_ok``)."""
    t = tab["t_s"]
    k = np.clip(np.searchsorted(times, t), 1, len(times) - 1)
    k = np.where(t - times[k - 1] <= times[k] - t, k - 1, k)
    outside = (t < times[0]) | (t > times[-1])
    if outside.any() and not outside_ok:
        i = int(np.flatnonzero(outside)[0])
        raise WorkbenchError(f"{path}, line {tab['lines'][i]}, column t_s: {float(t[i])!r} is outside the "
                             f"odometry's times ({float(times[0])!r} to {float(times[-1])!r})")
    return np.where(outside, -1, k)
