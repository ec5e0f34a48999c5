"""Real data for ``omni``: the UTIAS MRCLAM dataset read as bearing-only SLAM logs.

Dataset: K. Y. K. Leung, Y. Halpern, T. D. Barfoot, H. H. T. Liu, "The UTIAS Multi-Robot
Cooperative Localization and Mapping Dataset", International Journal of Robotics Research
30(8), 969-974, 2011. Educational and research use.

A dataset folder (``data/mrclam6``) holds, each after four ``#`` header lines and
whitespace-separated:

==========================  ================================================
``Robot{N}_Odometry.dat``     time [s], forward velocity v [m/s], yaw rate w [rad/s]
``Robot{N}_Measurement.dat``  time [s], barcode #, range [m], bearing [rad]
``Robot{N}_Groundtruth.dat``  time [s], x [m], y [m], heading [rad] (Vicon)
``Landmark_Groundtruth.dat``  subject #, x [m], y [m], std x [m], std y [m]
``Barcodes.dat``              subject #, barcode #
==========================  ================================================

The measurement file's header says "Subject #" but its second column holds *barcodes*;
``Barcodes.dat`` maps them to subjects. Subjects 1-5 are the robots, the landmarks are the
subjects listed in ``Landmark_Groundtruth.dat`` (6-20). Measurements of robots and of
barcodes with no subject are dropped and counted; the range is dropped (bearing-only).

Readings taken here (say so where a caller might assume otherwise):

* Times stay absolute (Unix seconds, float64 keeps the files' millisecond resolution);
  :attr:`MrclamLog.t0` is the start of the kept stretch, for plotting ``t - t0``.
* Real files have quirks a loader must meet rather than refuse; each repair is counted in
  :attr:`MrclamLog.repairs` and said in a :class:`~workbench.errors.DataWarning`:
  a row stamped out of time order by up to ``MAX_BACKSTEP`` seconds is put back in order
  (another MRCLAM dataset's odometry stamps its first sample 0.1 s after its second);
  a last line cut short (a log whose writer stopped mid-line) is left out; odometry and
  ground truth that repeat a time stamp (robot 2's odometry does once) keep the last row of
  each repeat, so their times are strictly increasing; gaps in the odometry over
  ``GAP`` seconds are counted (they need no repair: the motion model's noise grows with a
  step's duration, and :func:`.real.between` reads the next command as taking over at a time
  unknown within the step). Measurements share time stamps (several landmarks in one image), so
  their times are only non-decreasing. Time running backwards by more than ``MAX_BACKSTEP``,
  no rows, or too few columns anywhere but the last line stay errors.
* Text quirks (a BOM, ``;`` with decimal commas, quotes, ...) are repaired and counted by
  :mod:`workbench.io.text` (``odometry_bom``, ...); a clean file goes to numpy as is.
* The default stretch starts where the start pose is known from the ground truth *and*
  odometry exists: at the first ground-truth time, or at the first odometry time if that
  is later (in MRCLAM 6 the Vicon starts about 12 s before the odometry and the robots stand
  still meanwhile). It ends at the last odometry time within the ground truth's span (robot
  1's truth ends about two minutes before its odometry).
* The truth is optional, as on a researcher's own log: without ``Robot{N}_Groundtruth.dat``
  the log runs over its whole odometry (the first pose is then the origin); without
  ``Landmark_Groundtruth.dat`` every subject ``Barcodes.dat`` names that is not a robot is a
  landmark of unknown place. Each absence is said in a warning and counted in the repairs.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from workbench.errors import DataNotFound, WorkbenchError
from workbench.estimation.alignment import interpolate_pose
from workbench.estimation.angles import wrap
from workbench.io import csvfiles as csvfile
from workbench.io import text as textfile

ROBOT_SUBJECTS = frozenset(range(1, 6))
"""MRCLAM subject numbers of the robots (the landmarks are 6-20)."""

MAX_TRUTH_GAP = 0.5
"""Default longest ground-truth gap (s) :meth:`MrclamLog.truth_at` interpolates across."""
MAX_BACKSTEP = 1.0
"""The furthest back (s) a row's time stamp may lie and still be put back in order (a clock's
jitter, a row written late); beyond it the file's time runs backwards and is refused."""
GAP = 0.5
"""An odometry gap (s) counted as one in :attr:`MrclamLog.repairs`."""

_KINDS = {"odometry": "Odometry", "measurement": "Measurement", "groundtruth": "Groundtruth"}
_ROBOT_FILE = re.compile(r"^Robot(\d+)_(Odometry|Measurement|Groundtruth)\.dat$")


@dataclass
class MrclamLog:
    """One robot's log over one stretch of time; every array sorted by time.

    Times are absolute dataset seconds; ``t0`` and ``t_end`` bound the stretch (use ``t - t0``
    for plots). ``source`` is the dataset folder. Shapes: odometry ``(K,)``, measurements
    ``(M,)`` (bearings in the robot frame, wrapped to (-pi, pi]), truth ``(G,)`` and ``(G, 3)``.

    ``dropped`` counts rows left out within the stretch: ``"robot"`` (measurements of other
    robots), ``"unknown"`` (barcodes not in ``Barcodes.dat``), ``"no_truth"`` (subjects that are
    neither robots nor in ``Landmark_Groundtruth.dat``), ``"odom_repeat"`` and
    ``"truth_repeat"`` (rows with a repeated time stamp). The measurement keys are
    ``MEASUREMENT_DROPS``: ``M + sum(dropped[k] for k in MEASUREMENT_DROPS)`` is the number of
    measurement rows in the stretch.
    """

    robot: int
    odom_t: np.ndarray
    odom_v: np.ndarray
    odom_w: np.ndarray
    meas_t: np.ndarray
    meas_landmark: np.ndarray
    meas_bearing: np.ndarray
    truth_t: np.ndarray
    truth_pose: np.ndarray
    landmarks: dict[int, np.ndarray]
    dropped: dict[str, int]
    t0: float
    t_end: float
    source: Path = field(default_factory=Path)
    repairs: dict[str, int] = field(default_factory=dict)  # what was repaired to read the files (see the module)

    MEASUREMENT_DROPS = ("robot", "unknown", "no_truth")

    def truth_at(self, t: np.ndarray | float, max_gap: float = MAX_TRUTH_GAP) -> np.ndarray:
        """Ground-truth poses at times ``t`` (absolute s): an array ``(len(t), 3)`` of x, y, heading.

        Linear between the two surrounding Vicon samples; the heading is interpolated along the
        shorter arc and wrapped to (-pi, pi]. Rows are NaN where ``t`` lies outside the truth's
        span or inside a gap between samples longer than ``max_gap`` seconds (a time exactly on
        a sample is always valid).
        """
        return interpolate_pose(self.truth_t, self.truth_pose, t, max_gap)

    def landmark_array(self) -> tuple[np.ndarray, np.ndarray]:
        """Landmark subjects ``(L,)`` in ascending order and their true positions ``(L, 2)``."""
        ids = np.array(sorted(self.landmarks), dtype=int)
        return ids, np.array([self.landmarks[i] for i in ids]).reshape(-1, 2)


def robots_in(folder: Path) -> list[int]:
    """Robot numbers whose odometry and measurement files are in ``folder`` (the ground truth is optional)."""
    folder = _check_folder(folder)
    found: dict[int, set[str]] = {}
    for path in folder.iterdir():
        m = _ROBOT_FILE.match(path.name)
        if m and path.is_file():
            found.setdefault(int(m.group(1)), set()).add(m.group(2))
    return sorted(n for n, kinds in found.items() if {"Odometry", "Measurement"} <= kinds)


def load(folder: Path, robot: int, t_start: float | None = None, t_end: float | None = None) -> MrclamLog:
    """Load robot ``robot``'s log from an MRCLAM folder, kept from ``t_start`` to ``t_end``.

    ``t_start`` and ``t_end`` are absolute dataset times (s). By default the stretch starts at
    the first ground-truth time, or at the first odometry time if that is later, so the start
    pose is known from the ground truth and odometry runs from the first instant; it ends at the
    last odometry time within the ground truth's span. Explicit times are taken as given (the
    truth may then not cover them: :meth:`MrclamLog.truth_at` gives NaN there). Odometry and
    measurements are kept with ``t0 <= t <= t_end``; the ground truth keeps one sample either
    side of the stretch where it has them, so ``truth_at`` is defined at both ends.

    Raises :class:`WorkbenchError` (one line, naming the file and line) for a missing folder
    or file, an unknown robot, too few columns, unparsable or non-finite numbers, time going
    backwards, a non-integer barcode or subject, a repeated barcode or landmark, an empty file,
    or a stretch with no odometry.
    """
    folder = _check_folder(folder)
    files = {k: folder / f"Robot{robot}_{name}.dat" for k, name in _KINDS.items()}
    present = [p for p in files.values() if p.is_file()]
    if not present:
        robots = robots_in(folder)
        listed = ", ".join(map(str, robots)) if robots else "none"
        raise WorkbenchError(f"unknown robot {robot} in {folder}: available robots are {listed}")
    repairs: dict[str, int] = {}
    has_truth = files["groundtruth"].exists()
    if not has_truth:
        del files["groundtruth"]
        repairs["no_ground_truth"] = 1
        csvfile.say(folder / f"Robot{robot}_Groundtruth.dat", "absent: the run goes without the robot's truth "
                    "(the first pose is the origin; no errors, bounds or NEES)")
    for path in files.values():
        _check_file(path)

    subject_of = _read_barcodes(folder / "Barcodes.dat", repairs)
    if (folder / "Landmark_Groundtruth.dat").exists():
        landmarks = _read_landmarks(folder / "Landmark_Groundtruth.dat", repairs)
    else:
        landmarks = {s: np.full(2, np.nan) for s in sorted(set(subject_of.values()) - ROBOT_SUBJECTS)}
        repairs["no_landmark_truth"] = 1
        csvfile.say(folder / "Landmark_Groundtruth.dat", f"absent: the {len(landmarks)} subjects of Barcodes.dat "
                    "that are not robots are landmarks of unknown place (no map error)")

    raw = {"odometry": _read_table(files["odometry"], 3, repairs=repairs, cut=True),
           "measurement": _read_table(files["measurement"], 4, int_cols=(1,), repairs=repairs, cut=True)}
    if has_truth:
        raw["groundtruth"] = _read_table(files["groundtruth"], 4, repairs=repairs, cut=True)
    for kind, table in raw.items():  # on the file's rows, before any reordering: the lines named are the file's
        _check_ranges(files[kind], table, SANE[kind])
    odom = _in_order(files["odometry"], raw["odometry"], repairs)
    meas = _in_order(files["measurement"], raw["measurement"], repairs)
    truth = _in_order(files["groundtruth"], raw["groundtruth"], repairs) if has_truth else np.zeros((0, 4))
    gaps = int(np.sum(np.diff(odom[:, 0]) > GAP))
    if gaps:
        repairs["odometry_gaps"] = gaps
        longest = float(np.max(np.diff(odom[:, 0])))
        csvfile.say(files["odometry"], f"{gaps} gap(s) over {GAP:g} s between rows (longest {longest:.2f} s); "
                                "the next command is read as taking over at an unknown time within each")

    t0 = float(max(truth[0, 0] if has_truth else -np.inf, odom[0, 0])) if t_start is None else float(t_start)
    if t_end is None and not has_truth:
        t1 = float(odom[-1, 0])
    elif t_end is None:
        within = odom[odom[:, 0] <= truth[-1, 0], 0]
        if within.size == 0:
            raise WorkbenchError(f"{files['odometry']}: no odometry within the ground truth's span "
                                 f"({truth[0, 0]:.3f} to {truth[-1, 0]:.3f} s)")
        t1 = float(within[-1])
    else:
        t1 = float(t_end)
    if not (np.isfinite(t0) and np.isfinite(t1)) or t1 <= t0:
        raise WorkbenchError(f"robot {robot} in {folder}: empty stretch t_start = {t0:.3f} s, "
                             f"t_end = {t1:.3f} s")

    span = f"{odom[0, 0]:.3f} to {odom[-1, 0]:.3f} s"
    odom = odom[(odom[:, 0] >= t0) & (odom[:, 0] <= t1)]
    if odom.shape[0] == 0:
        raise WorkbenchError(f"{files['odometry']}: no odometry between {t0:.3f} and {t1:.3f} s "
                             f"(the file spans {span})")
    keep = csvfile.last_of_repeats(odom[:, 0])
    odom, odom_repeat = odom[keep], int((~keep).sum())
    if odom_repeat:
        csvfile.say(files["odometry"], f"{odom_repeat} repeated time stamp(s): the last row of each kept")
    meas = meas[(meas[:, 0] >= t0) & (meas[:, 0] <= t1)]
    lo = max(int(np.searchsorted(truth[:, 0], t0, side="right")) - 1, 0)
    hi = int(np.searchsorted(truth[:, 0], t1, side="left")) + 1
    keep = csvfile.last_of_repeats(truth[lo:hi, 0]) if has_truth else np.ones(len(truth), bool)
    truth, truth_repeat = (truth[lo:hi] if has_truth else truth)[keep], int((~keep).sum())
    if truth_repeat:
        csvfile.say(files["groundtruth"], f"{truth_repeat} repeated time stamp(s): the last row of each kept")

    barcode = meas[:, 1].astype(int)
    subject = np.array([subject_of.get(int(b), -1) for b in barcode], dtype=int)
    is_landmark = np.isin(subject, np.array(sorted(landmarks), dtype=int))
    is_robot = np.isin(subject, np.array(sorted(ROBOT_SUBJECTS))) & ~is_landmark
    unknown = subject < 0
    dropped = {"robot": int(is_robot.sum()), "unknown": int(unknown.sum()),
               "no_truth": int((~is_landmark & ~is_robot & ~unknown).sum()),
               "odom_repeat": odom_repeat, "truth_repeat": truth_repeat}
    meas = meas[is_landmark]
    pose = truth[:, 1:4].copy()
    pose[:, 2] = wrap(pose[:, 2])
    return MrclamLog(
        robot=int(robot),
        odom_t=odom[:, 0].copy(), odom_v=odom[:, 1].copy(), odom_w=odom[:, 2].copy(),
        meas_t=meas[:, 0].copy(), meas_landmark=subject[is_landmark],
        meas_bearing=np.asarray(wrap(meas[:, 3]), dtype=float).reshape(-1),
        truth_t=truth[:, 0].copy(), truth_pose=pose,
        landmarks=landmarks, dropped=dropped, t0=t0, t_end=t1, source=folder, repairs=repairs,
    )


# --- reading -------------------------------------------------------------------------------------

def _check_folder(folder: Path) -> Path:
    folder = Path(folder).expanduser()
    if not folder.exists():
        raise DataNotFound(f"MRCLAM folder not found: {folder} (set WORKBENCH_DATA or pass --data)")
    if not folder.is_dir():
        raise WorkbenchError(f"not a folder: {folder} (expected an MRCLAM dataset folder)")
    return folder


def _check_file(path: Path) -> None:
    if not path.exists():
        raise WorkbenchError(f"MRCLAM file missing: {path}")
    if not path.is_file():
        raise WorkbenchError(f"not a file: {path}")


def _what(path: Path) -> str:
    """The name a file's repairs are counted under (``odometry``, ``landmarks``, ``barcodes``, ...)."""
    return {"Landmark_Groundtruth": "landmarks"}.get(path.stem, path.stem.split("_")[-1].lower())


def _text(path: Path, repairs: dict | None, quiet: bool = False) -> textfile.Table:
    """The file through :mod:`.textfile` (whitespace, ``#`` comments, latin-1), its quirks counted."""
    return textfile.table(path, _what(path), {} if repairs is None else repairs, separator=textfile.WHITESPACE,
                          comments="#", encoding="latin-1", quiet=quiet)


def _data_lines(path: Path) -> list[tuple[int, list[str]]]:  # (1-based line number, tokens) of each data line
    return _text(path, None, quiet=True).rows


def _line_of(path: Path, row: int) -> int:
    """The file line number of data row ``row`` (0-based); used only when reporting an error."""
    return _data_lines(path)[row][0]


SANE = {  # column -> (what, lowest, highest): a ground robot indoors (MRCLAM's 15 x 8 m hall, 0.2 m/s)
    "odometry": ((1, "speed (m/s)", -50.0, 50.0), (2, "turn rate (rad/s)", -50.0, 50.0)),
    "measurement": ((2, "range (m)", 0.0, 1e4), (3, "bearing (rad)", -1e3, 1e3)),
    "groundtruth": ((1, "x (m)", -1e5, 1e5), (2, "y (m)", -1e5, 1e5), (3, "heading (rad)", -1e3, 1e3)),
}
"""Bounds no real log of a ground robot crosses: a value outside is corruption (1e300), said as
an error naming the file and line, never read on. Angles may be unwrapped (they are wrapped on
reading); a thousand radians is not an angle any log writes."""


def _check_ranges(path: Path, table: np.ndarray, checks: tuple) -> None:
    for col, what, lo, hi in checks:
        out = (table[:, col] < lo) | (table[:, col] > hi)
        if out.any():
            row = int(np.flatnonzero(out)[0])
            raise WorkbenchError(f"{path}: line {_line_of(path, row)}: {what} {table[row, col]:g} is outside "
                                 f"[{lo:g}, {hi:g}] (a corrupted value?)")


def _read_table(path: Path, ncols: int, int_cols: tuple[int, ...] = (), repairs: dict | None = None,
                cut: bool = False) -> np.ndarray:
    """The first ``ncols`` columns of a whitespace-separated ``#``-commented file, as floats.

    numpy's C parser, on the file where it has no text quirk (:func:`.textfile.plain`), else on
    :mod:`.textfile`'s rows; only when it fails is the file scanned to name the line. A last line
    cut short is left out (counted in ``repairs``) where ``cut``.
    """
    _check_file(path)
    source: Path | list[str] = path
    delimiter = None
    if not textfile.plain(path.read_bytes()):  # the fields one by one: a tab cannot be inside one
        source, delimiter = ["\t".join(fields) for _, fields in _text(path, repairs).rows], "\t"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            table = np.loadtxt(source, comments="#", delimiter=delimiter, usecols=range(ncols), ndmin=2,
                               dtype=float, encoding="latin-1")
    except (ValueError, UnicodeDecodeError) as exc:
        table = _without_cut_last_line(path, ncols) if cut and repairs is not None else None
        if table is None:
            _diagnose(path, ncols)
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise WorkbenchError(f"{path}: cannot parse: {first}") from None
        repairs["cut_last_line"] = repairs.get("cut_last_line", 0) + 1
    if table.shape[0] == 0:
        raise WorkbenchError(f"{path}: no data rows (the file is empty or only comments)")
    bad = ~np.isfinite(table)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise WorkbenchError(f"{path}: line {_line_of(path, int(row))}: non-finite value "
                             f"{table[row, col]} in column {col + 1}")
    for col in int_cols:
        frac = table[:, col] != np.round(table[:, col])
        if frac.any():
            row = int(np.argmax(frac))
            raise WorkbenchError(f"{path}: line {_line_of(path, row)}: column {col + 1} should be an "
                                 f"integer, got {table[row, col]:g}")
    return table


def _without_cut_last_line(path: Path, ncols: int) -> np.ndarray | None:
    """The table without its last data line, if that line alone is cut short: fewer columns than
    the table's (a log whose writer stopped mid-line; its last number may be cut too); None if
    anything else is wrong."""
    lines = _data_lines(path)
    if len(lines) < 2:
        return None

    def good(tokens: list[str]) -> bool:
        try:
            [float(t) for t in tokens[:ncols]]
        except ValueError:
            return False
        return len(tokens) >= ncols

    last = lines[-1][1]
    cut = len(last) < ncols and all(_number(t) for t in last[:-1])
    if not cut or not all(good(tokens) for _, tokens in lines[:-1]):
        return None
    csvfile.say(path, f"line {lines[-1][0]} is cut short ({' '.join(lines[-1][1])[:40]!r}): left out")
    return np.array([[float(t) for t in tokens[:ncols]] for _, tokens in lines[:-1]])


def _number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _diagnose(path: Path, ncols: int) -> None:
    """Raise a WorkbenchError naming the first line with too few columns or a bad number."""
    for number, tokens in _data_lines(path):
        if len(tokens) < ncols:
            raise WorkbenchError(f"{path}: line {number}: {len(tokens)} column(s), expected at least "
                                 f"{ncols}")
        for col, token in enumerate(tokens[:ncols], start=1):
            try:
                float(token)
            except ValueError:
                raise WorkbenchError(f"{path}: line {number}: cannot parse {token[:40]!r} in column "
                                     f"{col} as a number") from None


def _in_order(path: Path, table: np.ndarray, repairs: dict) -> np.ndarray:
    """The rows in time order (:func:`workbench.io.csvfiles.in_order`: rows up to ``MAX_BACKSTEP``
    s out of order put back, further an error naming the lines; repeats are handled by the caller)."""
    what = path.stem.split("_")[-1].lower()
    return table[csvfile.in_order(path, table[:, 0], lambda: [n for n, _ in _data_lines(path)], MAX_BACKSTEP,
                                  what, repairs)]


def _read_landmarks(path: Path, repairs: dict | None = None) -> dict[int, np.ndarray]:
    table = _read_table(path, 3, int_cols=(0,), repairs=repairs)
    subjects = table[:, 0].astype(int)
    _check_unique(path, subjects, "landmark subject")
    return {int(s): table[i, 1:3].copy() for i, s in enumerate(subjects)}


def _read_barcodes(path: Path, repairs: dict | None = None) -> dict[int, int]:
    table = _read_table(path, 2, int_cols=(0, 1), repairs=repairs).astype(int)
    _check_unique(path, table[:, 1], "barcode")
    return {int(b): int(s) for s, b in table}


def _check_unique(path: Path, values: np.ndarray, what: str) -> None:
    _, first, counts = np.unique(values, return_index=True, return_counts=True)
    if (counts > 1).any():
        value = values[first[np.argmax(counts > 1)]]
        rows = np.flatnonzero(values == value)
        raise WorkbenchError(f"{path}: line {_line_of(path, int(rows[1]))}: {what} {value} repeats "
                             f"(first on line {_line_of(path, int(rows[0]))})")
