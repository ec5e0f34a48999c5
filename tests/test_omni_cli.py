"""``workbench omni`` end to end: the recording read back, the metrics file, TUM export,
determinism, and bad input (one line, exit code 2, nothing written)."""

import json
from pathlib import Path

import numpy as np
import pytest
from launcher import DATA, cli

import workbench
from workbench.experiments.omni.readers import tum
from workbench.recording import readback

ALL = ("odometry", "ekf-paper", "ekf", "isam2", "gtsam-batch")
SHORT = ("--duration", "40")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("omni")
    out, m = d / "omni.rrd", d / "m.json"
    r = cli("omni", "--runs", "2", "--seed", "5", "--out", str(out), "--metrics", str(m), "--export-tum",
            str(d / "tum"), *SHORT)
    assert r.returncode == 0, r.stderr
    return d, out, json.loads(m.read_text())


def test_recording_has_every_estimator(recorded):
    _, out, stats = recorded
    rows = readback.row_counts(out)
    G = stats["grid_steps"]
    assert G == 201  # 40 s of bearings at 5 Hz, plus the start
    assert rows["/world/truth/vehicle"] == G
    for name in ALL:
        for path in ("vehicle", "pose_ellipse"):
            assert rows[f"/map/{name}/{path}"] >= G - 1, (name, path)  # the start pose has no ellipse
        assert rows[f"/errors/position/{name}"] == G and rows[f"/errors/heading/{name}"] == G
        assert rows[f"/monte_carlo/position/{name}"] == G
        assert rows[f"/map/{name}/rays"] == 200  # every bearing epoch
    for name in ("ekf", "ekf-paper"):
        assert rows[f"/map/{name}/landmarks"] == 200 and rows[f"/map/{name}/landmark_ellipses"] == 200
        assert rows[f"/map/{name}/pending"] > 0
        assert rows[f"/sigma/position/{name}"] == G and rows[f"/nees/{name}"] >= G - 5  # P singular at first
    assert rows["/map/isam2/landmarks"] > 10 and rows["/map/gtsam-batch/landmarks"] == 1
    # iSAM2's whole trajectory as held at the end: one static strip through every grid step, on
    # the batch smoother's path (within 2 cm)
    strips = readback.static_values(out, "/map/isam2/smoothed", "LineStrips3D:strips")
    smoothed = np.array(strips[0])[:, :2]
    batch = np.array(readback.static_values(out, "/map/gtsam-batch/path", "LineStrips3D:strips")[0])[:, :2]
    assert len(strips) == 1 and smoothed.shape == (G, 2)
    assert np.max(np.hypot(*(smoothed - batch).T)) < 0.02
    with pytest.raises(KeyError):
        readback.static_values(out, "/map/ekf/smoothed", "LineStrips3D:strips")
    props = readback.properties(out)
    assert props["experiment"] == "omni" and int(props["seed"]) == 5
    assert json.loads(props["config"])["runs"] == 2


def test_metrics_file_shape(recorded):
    _, _, stats = recorded
    assert stats["experiment"] == "omni" and stats["scenario"] == "paper" and stats["runs"] == 2
    for name in ALL:
        e = stats["estimators"][name]
        assert set(e["rmse"]) == {"position", "heading", "map"} and e["max"]["position"] >= e["rmse"]["position"]
        assert "anees" in e and e["seconds"] > 0
    assert stats["estimators"]["odometry"]["rmse"]["map"] is None
    # iSAM2 is a smoother: its trajectory at the end is the batch's; what it knew at each step is worse
    smoothed, bat = stats["estimators"]["isam2"]["rmse_smoothed_whole_run"], stats["estimators"]["gtsam-batch"]
    assert abs(smoothed["position"] - bat["rmse_whole_run"]["position"]) < 0.02
    assert smoothed["position"] < stats["estimators"]["isam2"]["rmse_whole_run"]["position"]
    assert "rmse_smoothed" not in stats["estimators"]["ekf"]
    assert stats["estimators"]["ekf"]["landmarks_initialised"] >= 15  # of 32, in 40 s


def test_tum_export_matches_the_metrics(recorded):
    d, _, stats = recorded
    t_truth, truth = tum.read_tum(d / "tum" / "truth.tum")
    t_ekf, ekf = tum.read_tum(d / "tum" / "ekf.tum")
    assert len(t_truth) == 1601 and len(t_ekf) == 1601  # every 0.025 s step
    assert set(p.name for p in (d / "tum").iterdir()) == {f"{n}.tum" for n in ("truth", *ALL)}
    grid = np.isin(np.round(t_ekf / 0.2, 6) % 1, [0.0])
    err = np.hypot(*(truth[:, :2] - ekf[:, :2]).T)[grid & (t_ekf >= stats["settle_seconds"])]
    assert np.isfinite(err).all()


def test_same_seed_same_numbers(tmp_path, recorded):
    _, _, stats = recorded
    m = tmp_path / "m.json"
    r = cli("omni", "--runs", "2", "--seed", "5", "--out", str(tmp_path / "a.rrd"), "--metrics", str(m), *SHORT,
            "--estimators", "odometry,ekf,gtsam-batch")
    assert r.returncode == 0, r.stderr
    again = json.loads(m.read_text())
    for name in ("odometry", "ekf", "gtsam-batch"):
        assert again["estimators"][name]["rmse"] == stats["estimators"][name]["rmse"]


def _mrclam_copy(tmp_path, mutate=None) -> Path:
    """A tiny MRCLAM folder: robot 1 drives a straight line past two landmarks."""
    d = tmp_path / "mr"
    d.mkdir()
    head = "# x\n# x\n# x\n# x\n"
    t = np.arange(0.0, 20.0, 0.02)
    (d / "Robot1_Odometry.dat").write_text(head + "".join(f"{x:.3f} 0.2 0.0\n" for x in t))
    truth = "".join(f"{x:.3f} {0.2 * x:.4f} 0.0 0.0\n" for x in t)
    (d / "Robot1_Groundtruth.dat").write_text(head + truth)
    lms = {6: (2.0, 1.5), 7: (3.0, -1.5)}
    rows = []
    for x in t[::10]:
        for s, (lx, ly) in lms.items():
            b = np.arctan2(ly, lx - 0.2 * x)
            if abs(b) < 0.6:
                rows.append(f"{x:.3f} {s + 10} 1.0 {b:.5f}\n")
    (d / "Robot1_Measurement.dat").write_text(head + "".join(rows))
    (d / "Landmark_Groundtruth.dat").write_text(head + "".join(f"{s} {x} {y} 0.001 0.001\n"
                                                               for s, (x, y) in lms.items()))
    (d / "Barcodes.dat").write_text(head + "1 5\n6 16\n7 17\n")
    if mutate:
        mutate(d)
    return d


def test_mrclam_folder_runs_every_estimator(tmp_path):
    d = _mrclam_copy(tmp_path)
    m = tmp_path / "m.json"
    r = cli("omni", "--scenario", "mrclam", "--data", str(d), "--out", str(tmp_path / "r.rrd"), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    stats = json.loads(m.read_text())
    assert set(stats["estimators"]) == set(ALL)
    assert stats["estimators"]["odometry"]["rmse"]["position"] < 0.05  # the odometry is exact here


def test_a_log_without_its_truth_runs(tmp_path):
    """The tiny robot starts at the origin, so its log without the ground-truth file (or the
    landmark file) gives the very same estimates: the truth only scores them. Without it the
    table has no pose errors, the map is scored against the landmark file alone, and the run
    says what it lacked."""
    d = _mrclam_copy(tmp_path)
    with_truth = workbench.run("omni", scenario="mrclam", data=d, estimators="odometry,ekf,gtsam-batch")
    (d / "Robot1_Groundtruth.dat").unlink()
    out, m = tmp_path / "n.rrd", tmp_path / "n.json"
    r = cli("omni", "--scenario", "mrclam", "--data", str(d), "--estimators", "odometry,ekf,gtsam-batch",
            "--out", str(out), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    assert "warning: Robot1_Groundtruth.dat: absent" in r.stderr and "Traceback" not in r.stderr
    stats = json.loads(m.read_text())
    assert stats["data_repairs"]["no_ground_truth"] == 1
    for name, e in stats["estimators"].items():
        assert e["position_rmse"] is None and e["anees"] is None and "position_bound" not in e, name
    without = workbench.run("omni", scenario="mrclam", data=d, estimators="odometry,ekf,gtsam-batch")
    assert np.isnan(without.data.truth).all() and np.array_equal(without.data.start, np.zeros(3))
    for name, est in with_truth.estimates.items():
        assert np.allclose(without.estimates[name].pose, est.pose, atol=1e-9), name
    (d / "Landmark_Groundtruth.dat").unlink()
    r = cli("omni", "--scenario", "mrclam", "--data", str(d), "--estimators", "odometry,gtsam-batch",
            "--out", str(tmp_path / "m.rrd"))
    assert r.returncode == 0 and "Landmark_Groundtruth.dat: absent" in r.stderr, r.stderr


def test_a_gap_in_the_commands_is_read_as_a_switch_and_shown(tmp_path):
    """The tiny robot stops for good at 10 s, but its log has no row from 9.5 s to 10.5 s: the
    switch reading runs the gap at half speed (the truth here: stopping at the gap's middle),
    the odometry ends within 1 cm of the truth, and the recording plots the heading sigma the
    gap's unknown switch adds, at the gap; holding the command before the gap runs 10 cm on."""
    def stop_at_10s(d):
        head = "# x\n# x\n# x\n# x\n"
        t = np.arange(0.0, 20.0, 0.02)
        t = t[(t < 9.5) | (t > 10.5)]
        rows = "".join(f"{x:.3f} {0.2 if x < 10 else 0.0} {0.1 if x < 10 else 0.0}\n" for x in t)
        (d / "Robot1_Odometry.dat").write_text(head + rows)
        fine = np.arange(0.0, 20.0, 0.001)  # the truth: the unicycle at 0.2 m/s, 0.1 rad/s, stopped at 10 s
        moving = fine < 10.0
        heading = np.cumsum(np.where(moving, 0.1, 0.0)) * 0.001
        x = np.cumsum(np.where(moving, 0.2 * np.cos(heading), 0.0)) * 0.001
        y = np.cumsum(np.where(moving, 0.2 * np.sin(heading), 0.0)) * 0.001
        (d / "Robot1_Groundtruth.dat").write_text(head + "".join(
            f"{fine[i]:.3f} {x[i]:.6f} {y[i]:.6f} {heading[i]:.6f}\n" for i in range(0, len(fine), 20)))

    d = _mrclam_copy(tmp_path, stop_at_10s)
    ends = {}
    for how in ("switch", "hold"):
        out, m = tmp_path / f"{how}.rrd", tmp_path / f"{how}.json"
        r = cli("omni", "--scenario", "mrclam", "--data", str(d), "--estimators", "odometry", "--out", str(out),
                "--metrics", str(m), "--odometry-between", how)
        assert r.returncode == 0, r.stderr
        ends[how] = json.loads(m.read_text())["estimators"]["odometry"]["final"]["position"]
        rows = readback.row_counts(out)
        assert rows.get("/odometry/switch/switch_heading_sigma", 0) == (1 if how == "switch" else 0)
    # the switch's mean runs the gap's distance (on the arc, to a millimetre); holding runs 0.5 s on
    assert ends["switch"] < 0.01 and ends["hold"] > 0.05

def _backwards(d):
    """Time running back by a minute (two rows swapped are put back in order: test_omni_mrclam)."""
    p = d / "Robot1_Odometry.dat"
    lines = p.read_text().splitlines(keepends=True)
    t, *rest = lines[11].split()
    lines[11] = " ".join([f"{float(t) - 60.0:.3f}", *rest]) + "\n"
    p.write_text("".join(lines))


def _few_columns(d):
    p = d / "Robot1_Measurement.dat"
    p.write_text("# x\n# x\n# x\n# x\n1.0 16\n")


@pytest.mark.parametrize("args,needle", [
    (["--runs", "0"], "--runs"),
    (["--sigma-v", "-1"], "non-negative"),
    (["--sigma-bearing", "-2"], "non-negative"),
    (["--skew-gate", "5"], "--skew-gate"),
    (["--nis-gate", "1.5"], "--nis-gate"),
    (["--min-parallax", "120"], "--min-parallax"),
    (["--scenario", "nowhere"], "scenario"),
    (["--estimators", "ekf,magic"], "unknown estimator"),
    (["--scenario", "mrclam", "--data", "/nonexistent/mrclam"], "nonexistent"),
    (["--scenario", "mrclam", "--robot", "9", "--data", "MRCLAM"], "robot"),
    (["--scenario", "mrclam", "--data", "BACKWARDS"], "backwards"),
    (["--scenario", "mrclam", "--data", "FEWCOLS"], "Robot1_Measurement.dat"),
])
def test_bad_input_one_line_exit_2(tmp_path, args, needle):
    subs = {"MRCLAM": lambda: _mrclam_copy(tmp_path), "BACKWARDS": lambda: _mrclam_copy(tmp_path, _backwards),
            "FEWCOLS": lambda: _mrclam_copy(tmp_path, _few_columns)}
    args = [str(subs[a]()) if a in subs else a for a in args]
    out = tmp_path / "x.rrd"
    r = cli("omni", "--out", str(out), *args)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr, r.stderr
    assert not out.exists()


def test_existing_output_not_overwritten(tmp_path):
    out = tmp_path / "keep.rrd"
    out.write_bytes(b"precious")
    r = cli("omni", "--out", str(out), "--duration", "5")
    assert r.returncode == 2 and "--force" in r.stderr
    assert out.read_bytes() == b"precious"


@pytest.mark.skipif(not (DATA / "mrclam6").is_dir(), reason="real MRCLAM data not present")
@pytest.mark.parametrize("robot", [1, 2, 3, 4, 5])
def test_real_robots(tmp_path, robot):
    """The whole log of every robot of dataset 6, one set of defaults: every estimator runs; the
    batch smoother is within 0.5 m RMS of the Vicon (and 3x better than dead reckoning), iSAM2's
    trajectory at the end within 2x of it, the EKF better than odometry, and aligning never hurts."""
    m = tmp_path / "m.json"
    r = cli("omni", "--scenario", "mrclam", "--robot", str(robot), "--out", str(tmp_path / "r.rrd"),
            "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    e = json.loads(m.read_text())["estimators"]
    odo = e["odometry"]["rmse"]["position"]
    batch = e["gtsam-batch"]["rmse"]["position"]
    assert batch <= 0.5 and batch * 3 < odo
    assert e["isam2"]["rmse_smoothed_whole_run"]["position"] <= 2 * batch
    assert e["ekf"]["rmse"]["position"] < odo  # the EKF does not diverge
    assert all(e[n]["coverage"] > 0.99 for n in ALL)
    assert all(e[n]["rmse_aligned"]["position"] <= e[n]["rmse"]["position"] + 1e-9 for n in ALL)


def test_from_images(tmp_path):
    out, m = tmp_path / "img.rrd", tmp_path / "m.json"
    r = cli("omni", "--from-images", "--duration", "20", "--estimators", "odometry,ekf,isam2", "--out", str(out),
            "--metrics", str(m), "--bad-frames", "4")
    assert r.returncode == 0, r.stderr
    im = json.loads(m.read_text())["images"]
    assert im["frames"] == 100 and im["bearing_rmse"] < 0.2 and im["detection_rate"] > 0.9
    assert im["association_rate"] > 0.85
    rows = readback.row_counts(out)
    reasons = [r for _, r in im["bad_frames"]]
    assert len(reasons) == 4 and any("empty" in r for r in reasons) and any("uint8" in r for r in reasons)
    assert rows["/camera/status"] == 4  # each refused frame is logged where it happened
    assert rows["/camera/round"] >= 18 and rows["/camera/detections"] == rows["/camera/round"]
    assert "Image stage" in r.stdout


def test_from_images_needs_the_simulation(tmp_path):
    r = cli("omni", "--from-images", "--scenario", "mrclam", "--out", str(tmp_path / "x.rrd"))
    assert r.returncode == 2 and "--from-images" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.skipif(not (DATA / "mrclam6").is_dir(), reason="real MRCLAM data not present")
def test_robot3_misreads_are_gated_and_the_smoother_holds():
    """Robot 3 of dataset 6 reads landmark 11's barcode as 20's four times at 255 s (172 deg
    from where 20 is): the gate leaves them out (the grown graph's 1 % of the rest come back when
    the batch re-gates against its own answer: under 0.5 % stay out), and the batch smoother ends
    within 0.5 m (RMS) of the truth, its heading within 5 deg; without the gate it turned the
    whole trajectory by 50 deg (3 m RMS)."""
    import warnings

    from workbench.estimation.angles import wrap
    from workbench.experiments.omni.algorithms import graph
    from workbench.experiments.omni.config import make_config
    from workbench.experiments.omni.readers import real

    cfg = make_config("mrclam", robot=3, data=DATA / "mrclam6").validate()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = real.load(cfg)
    est = graph.batch(data, cfg)
    t = data.t[data.meas_step[est.gated_bearings]]
    misread = (data.landmark_ids[data.meas_lm] == 20) & (np.abs(data.t[data.meas_step] - 255.5) < 1.0)
    assert misread.sum() == 4 and set(np.flatnonzero(misread)) <= set(est.gated_bearings.tolist())
    assert len(t) < 0.005 * len(data.meas_lm)
    truth = data.truth[est.steps]
    ok = np.isfinite(truth).all(axis=1)
    pos = np.hypot(*(est.pose[ok, :2] - truth[ok, :2]).T)
    head = np.degrees(np.abs(wrap(est.pose[ok, 2] - truth[ok, 2])))
    assert np.sqrt(np.mean(pos**2)) < 0.5 and np.sqrt(np.mean(head**2)) < 5.0


@pytest.mark.skipif(not (DATA / "mrclam6").is_dir(), reason="real MRCLAM data not present")
def test_the_recording_shows_the_gated_bearings(tmp_path):
    """Robot 3's first 300 s: the four misread bearings at 255 s are drawn red in the smoother's
    map, one ray at each step it came in, cleared at the next step; the metrics count them."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    out, m = tmp_path / "r3.rrd", tmp_path / "m.json"
    r = cli("omni", "--scenario", "mrclam", "--robot", "3", "--end-time", "300", "--estimators", "gtsam-batch",
            "--out", str(out), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    rows = []
    for chunk in RrdReader(str(out)).store().stream():
        if str(chunk.entity_path) == "/map/gtsam-batch/gated" and not chunk.is_static:
            batch = chunk.to_record_batch()
            t = batch.column("time").cast(pa.int64()).to_numpy(zero_copy_only=False) / 1e9
            rows += [(float(a), len(s or [])) for a, s in zip(t, batch.column("LineStrips3D:strips").to_pylist(),
                                                              strict=True)]
    rows.sort()
    burst = [n for t, n in rows if 254.5 < t < 255.9]
    assert burst == [1, 1, 1, 1]
    assert any(n == 0 for t, n in rows if 255.7 < t < 257.0)  # cleared after
    gated = json.loads(m.read_text())["estimators"]["gtsam-batch"]["bearings_gated"]
    assert gated == sum(n for _, n in rows) >= 4
