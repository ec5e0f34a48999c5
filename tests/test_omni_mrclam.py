"""The MRCLAM loader: parsing, dropping, wrapping, truth interpolation, windows, bad input, real data."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from workbench.errors import DataWarning, WorkbenchError
from workbench.estimation.angles import wrap
from workbench.experiments.omni.readers import mrclam
from workbench.paths import data_root

HEADER = ("# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\n"
          "# produced by a test\n# Data Format:\n# columns\n")
# Data row k (1-based) of a file written by ``write`` is on line 4 + k.

BARCODES = [(1, 5), (2, 14), (3, 41), (6, 63), (7, 81), (8, 7)]  # subject 8 has no landmark truth
LANDMARKS = [(6, 1.0, 2.0, 1e-4, 1e-4), (7, -3.0, 0.5, 1e-4, 1e-4)]
TRUTH = [  # time, x, y, heading; a 1 s gap between 102 and 103; 3.2 needs wrapping
    (100.0, 0.0, 0.0, 3.0), (100.5, 0.5, 0.0, 3.1), (101.0, 1.0, 0.0, 3.2), (101.5, 1.5, 1.0, -3.1),
    (102.0, 2.0, 1.0, 0.0), (103.0, 3.0, 1.0, 0.0), (103.5, 3.5, 1.0, 0.5)]
ODOM = [(100.2, 1.0, 0.1), (100.4, 1.0, 0.2), (100.4, 1.0, 0.3), (100.8, 1.0, 0.4), (101.6, 1.0, 0.5),
        (103.2, 1.0, 0.6), (103.5, 1.0, 0.7), (104.0, 1.0, 0.8)]
MEAS = [
    (100.1, 63, 1.0, 0.0),    # before the default start: cropped, not counted
    (100.3, 63, 2.0, 0.1),    # landmark 6
    (100.3, 14, 2.0, 0.2),    # robot 2
    (100.7, 99, 2.0, 0.3),    # unknown barcode
    (101.0, 81, 2.0, 3.5),    # landmark 7, bearing wraps
    (101.2, 7, 2.0, 0.0),     # subject 8: neither a robot nor a landmark with truth
    (101.2, 63, 2.0, -4.0),   # landmark 6, bearing wraps
    (103.6, 63, 2.0, 0.0),    # after the default end
]


def write(path: Path, rows, header: str = HEADER) -> Path:
    path.write_text(header + "".join(" \t".join(str(v) for v in row) + "\n" for row in rows))
    return path


def robot_files(folder: Path, robot: int, odom=ODOM, meas=MEAS, truth=TRUTH) -> None:
    write(folder / f"Robot{robot}_Odometry.dat", odom)
    write(folder / f"Robot{robot}_Measurement.dat", meas)
    write(folder / f"Robot{robot}_Groundtruth.dat", truth)


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    d = tmp_path / "mrclam"
    d.mkdir()
    write(d / "Barcodes.dat", BARCODES)
    write(d / "Landmark_Groundtruth.dat", LANDMARKS)
    robot_files(d, 1)
    robot_files(d, 3)
    write(d / "Robot2_Odometry.dat", ODOM)  # robot 2 is incomplete
    return d


def raises(match_file: str, *args, **kwargs) -> str:
    with pytest.raises(WorkbenchError) as info:
        mrclam.load(*args, **kwargs)
    message = str(info.value)
    assert match_file in message, message
    assert "\n" not in message
    return message


# --- parsing -------------------------------------------------------------------------------------

def test_robots_in_needs_all_three_files(folder):
    assert mrclam.robots_in(folder) == [1, 3]


def test_default_stretch_and_parsing(folder):
    log = mrclam.load(folder, 1)
    assert log.robot == 1
    # starts at the later of the first truth (100.0) and first odometry (100.2); ends at the last
    # odometry within the truth's span (103.5)
    assert log.t0 == 100.2 and log.t_end == 103.5
    np.testing.assert_array_equal(log.odom_t, [100.2, 100.4, 100.8, 101.6, 103.2, 103.5])
    np.testing.assert_array_equal(log.odom_w, [0.1, 0.3, 0.4, 0.5, 0.6, 0.7])  # last of a repeat kept
    np.testing.assert_array_equal(log.odom_v, np.ones(6))
    assert np.all(np.diff(log.odom_t) > 0)
    np.testing.assert_array_equal(log.meas_t, [100.3, 101.0, 101.2])
    np.testing.assert_array_equal(log.meas_landmark, [6, 7, 6])
    assert log.meas_landmark.dtype.kind == "i"
    np.testing.assert_allclose(log.meas_bearing, [0.1, 3.5 - 2 * np.pi, 2 * np.pi - 4.0])
    assert log.dropped == {"robot": 1, "unknown": 1, "no_truth": 1, "odom_repeat": 1, "truth_repeat": 0}
    assert set(log.landmarks) == {6, 7}
    np.testing.assert_array_equal(log.landmarks[7], [-3.0, 0.5])
    ids, xy = log.landmark_array()
    np.testing.assert_array_equal(ids, [6, 7])
    assert xy.shape == (2, 2)
    # the truth keeps a sample either side of the stretch and its headings are wrapped
    np.testing.assert_array_equal(log.truth_t, [t for t, *_ in TRUTH])
    assert log.truth_pose.shape == (7, 3)
    assert log.truth_pose[2, 2] == pytest.approx(3.2 - 2 * np.pi)
    assert np.all(np.abs(log.truth_pose[:, 2]) <= np.pi)
    assert np.all(np.isfinite(log.truth_at(log.odom_t)[[0, 1, 2, 3, 5]]))  # 103.2 lies in the gap


def test_bearings_wrap_to_half_open_interval(folder):
    meas = [(100.3, 63, 1.0, -np.pi), (100.4, 63, 1.0, np.pi), (100.5, 63, 1.0, 7.0)]
    write(folder / "Robot1_Measurement.dat", meas)
    log = mrclam.load(folder, 1)
    np.testing.assert_allclose(log.meas_bearing, [np.pi, np.pi, 7.0 - 2 * np.pi])


def test_explicit_window(folder):
    log = mrclam.load(folder, 1, t_start=100.5, t_end=101.6)
    assert log.t0 == 100.5 and log.t_end == 101.6
    np.testing.assert_array_equal(log.odom_t, [100.8, 101.6])
    np.testing.assert_array_equal(log.meas_t, [101.0, 101.2])
    np.testing.assert_array_equal(log.meas_landmark, [7, 6])
    assert log.dropped["robot"] == 0 and log.dropped["unknown"] == 1 and log.dropped["no_truth"] == 1
    np.testing.assert_array_equal(log.truth_t, [100.5, 101.0, 101.5, 102.0])
    # one side given: the other stays at its default
    assert mrclam.load(folder, 1, t_start=101.0).t_end == 103.5
    assert mrclam.load(folder, 1, t_end=101.0).t0 == 100.2
    # an explicit end past the truth is taken as given; truth_at is NaN there
    late = mrclam.load(folder, 1, t_start=103.0, t_end=104.0)
    np.testing.assert_array_equal(late.odom_t, [103.2, 103.5, 104.0])
    assert np.isnan(late.truth_at(np.array([104.0]))).all()


def test_odometry_starting_first_starts_at_truth(folder):
    odom = [(99.0, 1.0, 0.0), *ODOM]
    write(folder / "Robot1_Odometry.dat", odom)
    log = mrclam.load(folder, 1)
    assert log.t0 == 100.0 and log.odom_t[0] == 100.2



def test_format_variations_are_read(folder):
    """CRLF line ends, blank lines, trailing comments, extra columns and a non-UTF-8 header."""
    rows = "".join(f"{t}  {v}\t{w}   9.9 # note\r\n\r\n" for t, v, w in ODOM)
    (folder / "Robot1_Odometry.dat").write_bytes(("# caf\xe9 header\r\n" + rows).encode("latin-1"))
    log = mrclam.load(folder, 1)
    np.testing.assert_array_equal(log.odom_w, [0.1, 0.3, 0.4, 0.5, 0.6, 0.7])
    write(folder / "Robot1_Odometry.dat", [ODOM[0], (100.5, "x", 0.1)], header="# caf\xe9\n\n")
    assert "line 4" in raises("Robot1_Odometry.dat", folder, 1)


# --- truth_at ------------------------------------------------------------------------------------

def test_truth_at_interpolates_position_and_heading_on_the_circle(folder):
    log = mrclam.load(folder, 1)
    p = log.truth_at(np.array([100.25, 100.75, 101.25]))
    np.testing.assert_allclose(p[0], [0.25, 0.0, 3.05])
    # 3.1 -> 3.2 (= -3.083 wrapped) passes through pi, not through 0
    np.testing.assert_allclose(p[1], [0.75, 0.0, wrap(3.15)])
    assert abs(p[1, 2]) > 3.1
    np.testing.assert_allclose(p[2], [1.25, 0.5, wrap(3.2 + 0.5 * wrap(-3.1 - 3.2))])
    assert abs(p[2, 2]) > 3.0
    assert log.truth_at(100.25).shape == (1, 3)


def test_truth_at_is_nan_outside_and_in_gaps(folder):
    log = mrclam.load(folder, 1)
    t = np.array([99.9, 102.0, 102.5, 103.0, 103.5, 103.6])
    p = log.truth_at(t)
    assert np.isnan(p[[0, 2, 5]]).all()  # before, inside the 1 s gap, after
    np.testing.assert_allclose(p[[1, 3, 4]], [[2.0, 1.0, 0.0], [3.0, 1.0, 0.0], [3.5, 1.0, 0.5]])
    np.testing.assert_allclose(log.truth_at(np.array([102.5]), max_gap=2.0), [[2.5, 1.0, 0.0]])
    assert np.isnan(log.truth_at(np.array([100.25]), max_gap=0.1)).all()


def test_interpolate_pose_edge_cases():
    one = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(mrclam.interpolate_pose(np.array([5.0]), one, np.array([5.0, 6.0]))[0],
                                  one[0])
    assert np.isnan(mrclam.interpolate_pose(np.array([5.0]), one, np.array([6.0]))).all()
    assert mrclam.interpolate_pose(np.zeros(0), np.zeros((0, 3)), np.array([1.0])).shape == (1, 3)


# --- bad input -----------------------------------------------------------------------------------

def test_missing_folder(tmp_path):
    raises("nope", tmp_path / "nope", 1)
    with pytest.raises(WorkbenchError, match="nope"):
        mrclam.robots_in(tmp_path / "nope")


def test_folder_is_a_file(folder):
    raises("Barcodes.dat", folder / "Barcodes.dat", 1)


@pytest.mark.parametrize("name", ["Barcodes.dat", "Robot1_Odometry.dat", "Robot1_Measurement.dat"])
def test_missing_file(folder, name):
    """The files a log cannot go without (the truth's are optional: test_omni_cli)."""
    (folder / name).unlink()
    message = raises(name, folder, 1)
    assert "missing" in message


def test_unknown_robot_lists_available(folder):
    message = raises("robot 7", folder, 7)
    assert "1, 3" in message


def test_unknown_robot_in_empty_folder(tmp_path):
    assert "none" in raises("robot 1", tmp_path, 1)


BAD = [  # file, its rows, what the message must also say
    ("Robot1_Odometry.dat", [ODOM[0], (100.5, 1.0), *ODOM[3:]], ["line 6", "2 column(s)"]),
    ("Robot1_Odometry.dat", [ODOM[0], (100.5, "abc", 0.1), *ODOM[3:]], ["line 6", "'abc'"]),
    ("Robot1_Odometry.dat", [ODOM[0], (100.5, 1.0, "1,5"), *ODOM[3:]], ["line 6", "'1,5'"]),
    ("Robot1_Odometry.dat", [*ODOM[:3], (98.3, 1.0, 0.0), *ODOM[3:]], ["line 8", "backwards", "line 7",
                                                                     "more than 1 s"]),
    ("Robot1_Odometry.dat", [ODOM[0], (100.5, "inf", 0.0), *ODOM[3:]], ["line 6", "non-finite"]),
    ("Robot1_Measurement.dat", [*MEAS[:4], (99.6, 81, 2.0, 0.0), *MEAS[4:]], ["line 9", "backwards"]),
    ("Robot1_Measurement.dat", [MEAS[0], (100.2, 63, 2.0), MEAS[1]], ["line 6", "3 column(s)"]),
    ("Robot1_Measurement.dat", [MEAS[0], (100.2, 63.5, 2.0, 0.0)], ["line 6", "integer"]),
    ("Robot1_Measurement.dat", [MEAS[0], (100.2, 63, 2.0, "nan")], ["line 6", "non-finite"]),
    ("Robot1_Groundtruth.dat", [TRUTH[0], (100.5, 0.5, "nan", 3.1), *TRUTH[2:]], ["line 6", "non-finite"]),
    ("Robot1_Groundtruth.dat", [TRUTH[1], (98.0, 0.0, 0.0, 3.0)], ["line 6", "backwards"]),
    ("Robot1_Groundtruth.dat", [], ["no data"]),
    ("Landmark_Groundtruth.dat", [(6, 1.0)], ["line 5", "expected at least 3"]),
    ("Landmark_Groundtruth.dat", [*LANDMARKS, LANDMARKS[0]], ["line 7", "landmark subject 6 repeats"]),
    ("Barcodes.dat", [*BARCODES, (9, 63)], ["line 11", "barcode 63 repeats", "line 8"]),
    ("Barcodes.dat", [(1, "x5")], ["line 5", "'x5'"]),
    ("Barcodes.dat", [], ["no data"]),
]


@pytest.mark.parametrize(("name", "rows", "says"), BAD, ids=[f"{b[0]}-{i}" for i, b in enumerate(BAD)])
def test_bad_file(folder, name, rows, says):
    write(folder / name, rows)
    message = raises(name, folder, 1)
    for text in says:
        assert text in message, message


QUIRKS = {  # file, its rows, the repairs counted (beyond the fixture's own: two odometry gaps, one repeat)
    "first odometry sample stamped after the second": (
        "Robot1_Odometry.dat", [ODOM[1], ODOM[0], *ODOM[2:]], {"odometry_reordered": 2}),
    "a truth row 0.5 s out of order": (
        "Robot1_Groundtruth.dat", [TRUTH[1], TRUTH[0], *TRUTH[2:]], {"groundtruth_reordered": 2}),
    "a measurement written late": (
        "Robot1_Measurement.dat", [*MEAS[:4], (100.6, 81, 2.0, 0.0), *MEAS[4:]], {"measurement_reordered": 2}),
    "the odometry's last line cut short": (
        "Robot1_Odometry.dat", [*ODOM, (104.1, "1.")], {"cut_last_line": 1}),
    "the truth's last line cut mid-number": (
        "Robot1_Groundtruth.dat", [*TRUTH, (104.0, 4.0, "1.0e")], {"cut_last_line": 1}),
}


@pytest.mark.parametrize("quirk", list(QUIRKS))
def test_quirks_are_repaired_counted_and_said(folder, quirk):
    """What real files do that a loader must meet: repaired, counted, one warning line each;
    the rows as if the file had been clean."""
    clean = mrclam.load(folder, 1)
    name, rows, counted = QUIRKS[quirk]
    write(folder / name, rows)
    with pytest.warns(DataWarning) as said:
        log = mrclam.load(folder, 1)
    assert all(name in str(w.message) and "\n" not in str(w.message) for w in said if name in str(w.message))
    assert {k: log.repairs[k] for k in counted} == counted
    assert log.repairs["odometry_gaps"] == clean.repairs["odometry_gaps"] == 2   # 0.8 s and 1.6 s
    assert np.all(np.diff(log.odom_t) > 0) and np.all(np.diff(log.truth_t) > 0) and np.all(np.diff(log.meas_t) >= 0)
    if "measurement" not in name:
        np.testing.assert_array_equal(log.odom_t, clean.odom_t)
        np.testing.assert_array_equal(log.truth_pose, clean.truth_pose)
    else:
        assert len(log.meas_t) == len(clean.meas_t) + 1


def test_zero_byte_file(folder):
    (folder / "Robot1_Measurement.dat").write_bytes(b"")
    assert "no data" in raises("Robot1_Measurement.dat", folder, 1)


def test_binary_file(folder):
    (folder / "Robot1_Odometry.dat").write_bytes(bytes(range(256)) * 4)
    assert "binary" in raises("Robot1_Odometry.dat", folder, 1)


def test_empty_or_odometry_free_window(folder):
    assert "empty stretch" in raises("mrclam", folder, 1, t_start=101.0, t_end=101.0)
    assert "no odometry" in raises("Robot1_Odometry.dat", folder, 1, t_start=101.7, t_end=103.0)


def test_odometry_after_truth(folder):
    write(folder / "Robot1_Odometry.dat", [(104.0, 1.0, 0.0)])
    assert "ground truth" in raises("Robot1_Odometry.dat", folder, 1)


# --- the real dataset ----------------------------------------------------------------------------

MRCLAM = data_root() / "mrclam6"
needs_data = pytest.mark.skipif(not (MRCLAM / "Robot1_Odometry.dat").is_file(),
                                reason=f"MRCLAM dataset 6 not found at {MRCLAM} (set WORKBENCH_DATA)")


@pytest.fixture(scope="module", params=[1, 2, 3, 4, 5], ids=[f"robot{r}" for r in range(1, 6)])
def real(request) -> tuple[mrclam.MrclamLog, float]:
    if not (MRCLAM / "Robot1_Odometry.dat").is_file():
        pytest.skip(f"MRCLAM dataset 6 not found at {MRCLAM} (set WORKBENCH_DATA)")
    start = time.process_time()  # this process's CPU time: a loaded machine's other work is not counted
    log = mrclam.load(MRCLAM, request.param)
    return log, time.process_time() - start


@needs_data
def test_real_robots_listed():
    assert mrclam.robots_in(MRCLAM) == [1, 2, 3, 4, 5]


@needs_data
def test_real_sizes_and_drops(real):
    log, seconds = real
    assert seconds < 3.0  # (0.3-0.6 s here alone; 1.04 s seen with the suite on both cores: a guard, not a benchmark)
    assert 40_000 < log.odom_t.size < 70_000
    assert 40_000 < log.truth_t.size < 70_000
    assert 1_000 < log.meas_t.size < 5_000
    assert 600 < log.t_end - log.t0 < 1000
    assert np.all(np.diff(log.odom_t) > 0) and np.all(np.diff(log.truth_t) > 0)
    assert np.all(np.diff(log.meas_t) >= 0)
    assert set(np.unique(log.meas_landmark)) <= set(range(6, 21)) == set(log.landmarks)
    total = log.meas_t.size + sum(log.dropped[k] for k in log.MEASUREMENT_DROPS)
    fraction = 1.0 - log.meas_t.size / total
    assert 0.15 < fraction < 0.25, fraction  # the README: about 20 % are of other robots
    # the README names robot 1's one unknown barcode; the later robots have a few (2 and 3 in 3 and 4)
    assert log.dropped["unknown"] <= 3 and (log.robot != 1 or log.dropped["unknown"] == 1)
    assert np.all(np.abs(log.meas_bearing) < np.deg2rad(35.0))
    # the default stretch is covered but for Vicon's gaps over 0.3 s (robot 4 has 2.0 s and 0.55 s)
    covered = np.isfinite(log.truth_at(log.odom_t)[:, 0])
    assert covered.mean() > 0.995 and (covered.all() or log.robot == 4)


@needs_data
def test_real_bearings_agree_with_truth(real):
    log, _ = real
    pose = log.truth_at(log.meas_t)
    ok = np.isfinite(pose[:, 0])
    assert ok.mean() > 0.99
    lm = np.array([log.landmarks[i] for i in log.meas_landmark])
    predicted = np.arctan2(lm[:, 1] - pose[:, 1], lm[:, 0] - pose[:, 0]) - pose[:, 2]
    residual = np.abs(wrap(log.meas_bearing - predicted))[ok]
    assert np.median(residual) < np.deg2rad(3.0)
    assert np.percentile(residual, 95) < np.deg2rad(5.0)


@needs_data
def test_real_odometry_yaw_rate_leads_truth(real):
    """The README: the odometry's yaw rate leads the truth's by about 0.16 s."""
    log, _ = real
    dt = 0.01
    grid = np.arange(log.t0, log.t_end, dt)
    heading = np.convolve(np.unwrap(log.truth_at(grid, max_gap=np.inf)[:, 2]), np.ones(10) / 10, mode="same")
    w_truth = np.gradient(heading, dt)[20:-20]
    held = np.clip(np.searchsorted(log.odom_t, grid, side="right") - 1, 0, None)
    w_odom = log.odom_w[held][20:-20]
    lags = np.arange(0, 51)
    corr = [np.corrcoef(w_odom[: w_odom.size - k], w_truth[k:])[0, 1] for k in lags]
    lag = lags[int(np.argmax(corr))] * dt
    assert 0.05 < lag < 0.3 and max(corr) > 0.7



@needs_data
def test_real_gaps_read_as_a_switch_at_an_unknown_time(real):
    """Across the log's gaps (rows over 0.1 s apart) the switch reading's heading change, over the
    sigma it predicts (the density's and the switch's), squared, averages near 1 on every robot;
    on robot 4, whose gaps carry a quarter of its distance, holding the command before a gap
    runs a third too far against the Vicon and the switch's mean within 10 %."""
    from workbench.experiments.omni.readers.real import between

    log, _ = real
    t, cmds = log.odom_t, np.column_stack([log.odom_v, log.odom_w])
    dt = np.diff(t)
    mean, var = between(cmds)
    gap = np.flatnonzero(dt > 0.1)
    a, b = log.truth_at(t[gap]), log.truth_at(t[gap + 1])
    ok = np.isfinite(a[:, 2]) & np.isfinite(b[:, 2])
    gap, a, b = gap[ok], a[ok], b[ok]
    turned = wrap(b[:, 2] - a[:, 2])
    predicted = np.deg2rad(2.0) ** 2 * dt[gap] + var[gap, 1] * dt[gap] ** 2 + np.deg2rad(0.5) ** 2  # + the Vicon's
    z2 = (mean[gap, 1] * dt[gap] - turned) ** 2 / predicted
    assert 0.5 < z2.mean() < 2.0, z2.mean()
    if log.robot == 4:
        moved = np.hypot(*(b[:, :2] - a[:, :2]).T).sum()
        assert np.sum(cmds[gap, 0] * dt[gap]) > 1.3 * moved
        assert abs(np.sum(mean[gap, 0] * dt[gap]) / moved - 1.0) < 0.1

@needs_data
def test_a_quirky_real_log_runs_with_its_repairs_said(tmp_path):
    """Robot 1's real files with two quirks written in (its first odometry sample stamped after
    the second, a last line cut short) run through the command line: one warning line per repair,
    the counts in the metrics; time running back by a minute is one line and exit 2."""
    import json
    import shutil

    from launcher import cli

    d = tmp_path / "quirky"
    d.mkdir()
    for f in ("Barcodes.dat", "Landmark_Groundtruth.dat", "Robot1_Measurement.dat", "Robot1_Groundtruth.dat"):
        shutil.copy(MRCLAM / f, d / f)
    lines = (MRCLAM / "Robot1_Odometry.dat").read_text().splitlines(keepends=True)
    head, rows = lines[:4], lines[4:]
    (d / "Robot1_Odometry.dat").write_text("".join(head + [rows[1], rows[0]] + rows[2:] + ["1248273512.1 0.1"]))
    r = cli("omni", "--scenario", "mrclam", "--data", str(d), "--robot", "1", "--end-time", "60",
            "--estimators", "odometry,ekf", "--out", str(tmp_path / "q.rrd"), "--metrics", str(tmp_path / "q.json"))
    assert r.returncode == 0, r.stderr
    assert "warning: Robot1_Odometry.dat: 2 row(s) out of time order" in r.stderr
    assert "warning: Robot1_Odometry.dat: line" in r.stderr and "cut short" in r.stderr
    repairs = json.loads((tmp_path / "q.json").read_text())["data_repairs"]
    assert repairs["odometry_reordered"] == 2 and repairs["cut_last_line"] == 1
    t = float(rows[100].split()[0])
    bad = rows[:200] + [f"{t - 60.0:.3f} 0.0 0.0\n"] + rows[200:]
    (d / "Robot1_Odometry.dat").write_text("".join(head + bad))
    r = cli("omni", "--scenario", "mrclam", "--data", str(d), "--robot", "1", "--out", str(tmp_path / "b.rrd"))
    assert r.returncode == 2 and "time goes backwards" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("kind, row, col, value, needle", [
    ("Odometry", 2, 1, 1e300, "speed (m/s) 1e+300 is outside"),
    ("Odometry", 0, 2, -99.0, "turn rate (rad/s) -99 is outside"),
    ("Measurement", 1, 2, -1.0, "range (m) -1 is outside"),
    ("Groundtruth", 3, 1, 1e300, "x (m) 1e+300 is outside"),
])
def test_corrupted_values_are_one_line_naming_the_line(folder, kind, row, col, value, needle):
    """A value no ground robot's log has (1e300, a negative range) is an error naming the file's
    line (the header is 4 lines), not a number read on."""
    rows = [list(r) for r in {"Odometry": ODOM, "Measurement": MEAS, "Groundtruth": TRUTH}[kind]]
    rows[row][col] = value
    write(folder / f"Robot1_{kind}.dat", rows)
    with pytest.raises(WorkbenchError) as err:
        mrclam.load(folder, 1)
    message = str(err.value)
    assert needle in message and f"Robot1_{kind}.dat: line {HEADER.count(chr(10)) + row + 1}:" in message
    assert "\n" not in message
