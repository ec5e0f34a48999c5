"""An omni log of your own in the open format (``docs/log-formats.md``): run 0 of any scenario
written out (``--export-data``) and read back (``--scenario log --data``) gives the same estimates;
a log without its truth, with a sparse one, or without landmark ids runs; malformed logs are one
line naming the file, the line and the column, exit 2, nothing written."""

import dataclasses
import json
import shutil

import numpy as np
import pytest
from launcher import DATA, bad_logs_say_one_line, cli, edit_line

import workbench
from workbench.metrics import diagnosis
from workbench.recording import blueprints, readback

ALL = "odometry,ekf-paper,ekf,isam2,gtsam-batch"


def _export(tmp_path, scenario: str, estimators: str = ALL, **settings):
    """Run 0 of ``scenario`` written out as a log; ``estimators`` only where their estimates are read (the
    log is the data alone: the same whichever run)."""
    folder = tmp_path / scenario
    res = workbench.run("omni", scenario=scenario, runs=1, estimators=estimators, export_data=folder, **settings)
    return res, folder


def test_a_log_runs_from_the_command_line_on_its_own_defaults(tmp_path):
    _, folder = _export(tmp_path, "paper", estimators="odometry", duration=40.0)
    out, m = tmp_path / "log.rrd", tmp_path / "log.json"
    r = cli("omni", "--scenario", "log", "--data", str(folder), "--out", str(out), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    stats = json.loads(m.read_text())
    assert stats["scenario"] == "log" and set(stats["estimators"]) >= {"ekf", "isam2", "gtsam-batch"}
    assert stats["estimators"]["gtsam-batch"]["position_rmse"] < 1.0
    assert out.stat().st_size > 0


def _read_back(res, folder, estimators: str = ALL, **overrides):
    """The log read with the very estimator settings the original scenario had."""
    cfg = dataclasses.replace(res.config, scenario="log", data=folder, **overrides)
    return workbench.run("omni", config=cfg, estimators=estimators)


PAPER_60 = {"duration": 60.0}


@pytest.fixture(scope="module")
def paper_60(tmp_path_factory):
    """The paper's run 0 for 60 s with every estimator, exported, and read back (the same estimates):
    built once for the tests that read it (none changes it)."""
    res, folder = _export(tmp_path_factory.mktemp("paper_60"), "paper", **PAPER_60)
    return res, folder, _read_back(res, folder)


@pytest.fixture(scope="module")
def paper_120(tmp_path_factory):
    """The paper's run 0 for 120 s exported (its data alone) and read back with every estimator."""
    res, folder = _export(tmp_path_factory.mktemp("paper_120"), "paper", estimators="odometry", duration=120.0)
    return res, folder, _read_back(res, folder)


@pytest.mark.parametrize("scenario,settings", [
    ("paper", PAPER_60),
    ("images", {"duration": 40.0, "from_images": True}),
    ("mrclam", {"robot": 2, "end_time": 150.0}),
])
def test_an_exported_run_reads_back_to_the_same_estimates(tmp_path, request, scenario, settings):
    if scenario == "mrclam" and not (DATA / "mrclam6").is_dir():
        pytest.skip(f"no MRCLAM data at {DATA}")
    if scenario == "paper":   # the module's own (its config has from_images False already)
        res, folder, back = request.getfixturevalue("paper_60")
    else:
        res, folder = _export(tmp_path, "paper" if scenario == "images" else scenario, **settings)
        back = _read_back(res, folder, from_images=False)
    files = {p.name for p in folder.iterdir()}
    assert {"manifest.json", "odometry.csv", "bearings.csv", "truth.csv", "landmarks.csv"} <= files
    a, b = res.data, back.data
    assert np.array_equal(a.t, b.t) and np.array_equal(a.controls, b.controls)
    assert np.array_equal(a.meas_step, b.meas_step) and np.array_equal(a.meas_bearing, b.meas_bearing)
    for name, est in res.estimates.items():
        other = back.estimates[name]
        assert np.array_equal(other.steps, est.steps), name
        assert np.allclose(other.pose, est.pose, rtol=0, atol=1e-9), name
        assert np.allclose(other.final_map, est.final_map, rtol=0, atol=1e-9, equal_nan=True), name
    for name, e in res.metrics["estimators"].items():
        assert back.metrics["estimators"][name]["position_rmse"] == pytest.approx(e["position_rmse"], rel=1e-9)


def test_without_truth_with_a_sparse_one_and_without_landmark_ids(tmp_path, paper_60):
    res, folder, _ = paper_60
    bare = tmp_path / "bare"
    shutil.copytree(folder, bare)
    (bare / "truth.csv").unlink()
    out, m = tmp_path / "bare.rrd", tmp_path / "bare.json"
    workbench.run("omni", config=dataclasses.replace(res.config, scenario="log", data=bare), estimators=ALL,
                  out=out, metrics=m)
    stats = json.loads(m.read_text())["estimators"]
    assert stats["ekf"]["position_rmse"] is None and stats["ekf"]["anees"] is None
    assert stats["ekf"]["consistent_without_truth"] is not None
    # the recording's reference is the smoother: each estimate's departure from it, and each causal
    # estimator's disagreement with it, named so
    names = [v.name for v in blueprints.layout(out).views()]
    assert any(n.startswith("departure from gtsam-batch, position (m)") for n in names)
    assert not any(n.startswith("position error") for n in names)
    verdict = next(n for n in names if n.startswith("disagreement with gtsam-batch (3 dof, grey band)"))
    # each failing estimator named with its truth-free diagnosis
    failing = [k + (f" ({diagnosis.line(e['diagnosis'])})" if e.get("diagnosis") else "")
               for k, e in stats.items() if e.get("consistent_without_truth") is False]
    assert any(f.startswith("ekf-paper (") for f in failing) and "; failing: " + ", ".join(failing) in verdict
    t, d = readback.series(out, "/errors/position/ekf")
    ekf, ref = res.estimates["ekf"], res.estimates["gtsam-batch"]
    want = np.hypot(*(ref.pose[:, :2] - ekf.pose[np.searchsorted(ekf.steps, ref.steps), :2]).T)
    assert len(d) == len(ref.steps) and np.allclose(d, want, atol=1e-9)
    # the survey still scores the map
    assert stats["gtsam-batch"]["map_rmse"] == pytest.approx(res.metrics["estimators"]["gtsam-batch"]["map_rmse"],
                                                            rel=1e-6)
    # a sparse truth, position only (a fix every 5 s): the errors at those steps alone
    sparse = tmp_path / "sparse"
    shutil.copytree(folder, sparse)
    rows = np.loadtxt(folder / "truth.csv", delimiter=",", skiprows=1)
    keep = rows[::200]
    (sparse / "truth.csv").write_text("t_s,x_m,y_m\n" + "".join(",".join(repr(float(v)) for v in r[:3]) + "\n"
                                                                  for r in keep))
    back = _read_back(res, sparse)
    est = back.estimates["gtsam-batch"]
    on = np.isin(est.steps, np.searchsorted(res.data.t, keep[:, 0]))
    e = res.data.truth[est.steps[on], :2] - est.pose[on, :2]
    want = np.sqrt(np.mean(np.sum(e ** 2, axis=1)))
    got = back.metrics["estimators"]["gtsam-batch"]["position_rmse_whole_run"]
    assert on.sum() >= 10 and got == pytest.approx(want, rel=1e-9)
    assert back.metrics["estimators"]["gtsam-batch"]["heading_rmse"] is None
    # bearings without landmark ids: the association front end decides, and the batch still maps
    anonymous = tmp_path / "anonymous"
    shutil.copytree(folder, anonymous)
    rows = np.loadtxt(folder / "bearings.csv", delimiter=",", skiprows=1)
    (anonymous / "bearings.csv").write_text("t_s,bearing_rad\n" + "".join(",".join(repr(float(v)) for v in r[:2])
                                                                          + "\n" for r in rows))
    back = _read_back(res, anonymous)
    assert back.data.repairs.get("bearings_unassociated", 0) < 0.15 * len(rows)  # measured: 9 %
    rmse = {k: v["position_rmse"] for k, v in back.metrics["estimators"].items()}
    # measured (60 s): odometry 1.12 m; with ids ekf 0.29, gtsam-batch 0.34; without ekf 0.64, gtsam-batch 0.87
    assert rmse["gtsam-batch"] < 0.9 * rmse["odometry"] and rmse["ekf"] < 0.7 * rmse["odometry"]


BAD = [  # (file, how to break it, what the one line must say)
    ("manifest.json", lambda t: "not json", ["manifest.json", "not JSON"]),
    ("manifest.json", lambda t: t.replace('"motion": "bicycle"', '"motion": "tank"'), ["motion"]),
    ("manifest.json", lambda t: t.replace('"sigma_bearing_rad"', '"sigma_b"'), ["sigma_bearing_rad"]),
    ("manifest.json", lambda t: t.replace('"wheelbase_m": 4.0', '"wheelbase_m": -4'), ["wheelbase_m"]),
    ("manifest.json", lambda t: t.replace('"start": [', '"start": [1, '), ["start", "3 finite"]),
    ("odometry.csv", lambda t: "", ["odometry.csv", "no header"]),
    ("odometry.csv", lambda t: t.splitlines()[0] + "\n", ["odometry.csv", "no rows"]),
    ("odometry.csv", lambda t: t.replace("steering_rad", "gamma"), ["odometry.csv", "missing column", "steering_rad"]),
    ("odometry.csv", lambda t: edit_line(t, 5, lambda f: [f[0], "nan", *f[2:]]), ["odometry.csv", "line 5", "v_mps"]),
    ("odometry.csv", lambda t: edit_line(t, 5, lambda f: [f[0], f[1], "inf"]), ["odometry.csv", "line 5", "steering"]),
    ("odometry.csv", lambda t: edit_line(t, 40, lambda f: ["-9.0", *f[1:]]), ["odometry.csv", "line 40", "backwards"]),
    ("bearings.csv", lambda t: t.replace("bearing_rad", "angle"), ["bearings.csv", "missing column", "bearing_rad"]),
    ("bearings.csv", lambda t: edit_line(t, 4, lambda f: [f[0], "3.5", f[2]]), ["bearings.csv", "line 4", "bearing_rad",
                                                                           "beyond"]),
    ("bearings.csv", lambda t: edit_line(t, 4, lambda f: [f[0], f[1], "2.5"]), ["bearings.csv", "line 4", "landmark_id",
                                                                           "not an integer"]),
    ("bearings.csv", lambda t: edit_line(t, 4, lambda f: [f[0], f[1], "x"]), ["bearings.csv", "line 4", "landmark_id"]),
    ("bearings.csv", lambda t: edit_line(t, 4, lambda f: [f[0], "", f[2]]), ["bearings.csv", "line 4", "bearing_rad"]),
    ("bearings.csv", lambda t: t + "1000.0,0.1,3\n", ["bearings.csv", "t_s", "outside the odometry"]),
    ("truth.csv", lambda t: t.splitlines()[0] + "\n1000.0,1,2,3\n", ["truth.csv", "covers none of the run"]),
    ("truth.csv", lambda t: t.replace("y_m", "north"), ["truth.csv", "missing column", "y_m"]),
    ("landmarks.csv", lambda t: edit_line(t, 3, lambda f: ["1.5", *f[1:]]), ["landmarks.csv", "line 3", "landmark_id"]),
]


def test_malformed_logs_are_one_line_and_exit_2(tmp_path):
    _, folder = _export(tmp_path, "paper", estimators="odometry", duration=20.0)
    assert len(BAD) == 20
    bad_logs_say_one_line("omni", folder, tmp_path, BAD)


def _as_increments(d):
    """The dataset's odometry as the relative poses its controls give step by step, with their
    covariance (each step propagated from the origin: its body frame), ``Q`` included."""
    from workbench.experiments.omni.motion import Motion

    u, dt, var = d.odometry()
    inc, cov = np.zeros((len(u), 3)), np.zeros((len(u), 3, 3))
    for k in range(len(u)):
        poses, covs, _ = d.motion.propagate(np.zeros(3), np.zeros((3, 3)), u[k:k + 1], dt[k:k + 1],
                                            None if var is None else var[k:k + 1])
        inc[k], cov[k] = poses[1], covs[1]
    return dataclasses.replace(d, controls=inc, control_var=cov, motion=Motion("increments", 0.0, (0.0,) * 3))


def test_odometry_as_relative_pose_increments_gives_the_same_estimates(tmp_path, paper_60):
    """The graph-SLAM convention (g2o's EDGE_SE2): the same run's odometry written as relative poses
    with their covariances is the same motion, so every estimator lands where it did from the
    paper's bicycle controls (to rounding; iSAM2's relinearisation thresholds amplify it). The
    paper's own EKF is left out: it diverges on this run, and a divergence amplifies anything."""
    from workbench.experiments.omni.readers import log

    res, folder, back = paper_60
    inc = tmp_path / "increments"
    log.write(_as_increments(back.data), inc)
    meta = json.loads((inc / "manifest.json").read_text())
    head = (inc / "odometry.csv").read_text().splitlines()[0].split(",")
    assert meta["motion"] == "increments" and head[:4] == ["t_s", "dx_m", "dy_m", "dphi_rad"] and len(head) == 10
    other = _read_back(res, inc)
    assert other.data.motion.model == "increments" and other.data.control_var.shape == (len(back.data.t) - 1, 3, 3)
    for name, tol in (("odometry", 1e-9), ("ekf", 1e-5), ("gtsam-batch", 1e-5), ("isam2", 1e-3)):
        a, b = back.estimates[name], other.estimates[name]
        assert np.nanmax(np.abs(a.pose - b.pose)) < tol, name
        assert np.nanmax(np.abs(a.cov - b.cov)) < tol, name
    # the sigmas alone, without the covariance columns: the manifest's three per step
    bare = tmp_path / "sigmas"
    shutil.copytree(inc, bare)
    rows = [line.split(",")[:4] for line in (inc / "odometry.csv").read_text().splitlines()]
    (bare / "odometry.csv").write_text("\n".join(",".join(r) for r in rows) + "\n")
    (bare / "manifest.json").write_text(json.dumps(meta | {"sigma_dx_m": 0.02, "sigma_dy_m": 0.01,
                                                          "sigma_dphi_rad": 0.002}))
    d = _read_back(res, bare, estimators="odometry").data   # the log as read: no estimate of it is looked at
    assert d.control_var is None and d.motion.sigma_u == (0.02, 0.01, 0.002)
    bad_logs_say_one_line("omni", inc, tmp_path / "bad", [
        ("odometry.csv", lambda t: edit_line(t, 3, lambda f: [*f[:4], "-1.0", *f[5:]]),
         ["odometry.csv", "line 3", "not positive semi-definite"]),
        ("odometry.csv", lambda t: t.replace(",cov_dy_dphi_mrad", ",other"),
         ["needs every one of", "cov_dy_dphi_mrad"]),
        ("manifest.json", lambda t: t.replace('"sigma_dx_m": 0.0', '"sigma_dx_m": -0.1'),
         ["manifest.json", "sigma_dx_m"]),
        ("manifest.json", lambda t: t.replace('"noise_per_second": false', '"noise_per_second": true'),
         ["noise_per_second must be false"]),
    ])


def test_a_noisy_position_fix_is_scored_with_its_noise(tmp_path, paper_120):
    """A GPS-like track (a position every 5 s, 0.5 m noise per axis, ``sigma_m``): the errors at
    those times only, and the position NEES against the fix with its noise added to the estimate's
    covariance (chi-square 2 for a consistent estimator); the paper's EKF is caught by it too."""
    from workbench.experiments.omni.readers import log

    res, _, back = paper_120
    d = back.data
    every, sigma = np.arange(0, len(d.t), 50), 0.5
    truth, ts = np.full_like(d.truth, np.nan), np.full(len(d.t), np.nan)
    truth[every, :2] = d.truth[every, :2] + np.random.default_rng(5).normal(0.0, sigma, (len(every), 2))
    ts[every] = sigma
    gps = tmp_path / "gps"
    log.write(dataclasses.replace(d, truth=truth, truth_sigma=ts), gps)
    assert (gps / "truth.csv").read_text().splitlines()[0] == "t_s,x_m,y_m,sigma_m"
    g = _read_back(res, gps)
    assert np.array_equal(np.isfinite(g.data.truth_sigma), np.isfinite(ts))
    stats = g.metrics["estimators"]
    for name in ("ekf", "isam2", "gtsam-batch"):
        e = stats[name]
        assert e["anees"] is None and 1.0 < e["fix_nees"] < 3.5, (name, e["fix_nees"])
        # the error against the fix holds the fix's own noise: sqrt(2) 0.5 m radial besides the estimate's
        own = back.metrics["estimators"][name]["position_rmse"]
        assert np.hypot(own, 0.5 * np.sqrt(2)) * 0.7 < e["position_rmse"] < np.hypot(own, 0.5 * np.sqrt(2)) * 1.3
    assert stats["ekf-paper"]["fix_nees"] > 100
    assert back.metrics["estimators"]["ekf"].get("fix_nees") is None  # an exact pose: the pose NEES holds


def test_each_bearing_weighed_by_its_own_sigma(tmp_path, paper_120):
    """A log whose bearings carry their own sigma (``sigma_rad``; here 30 % of them five times as
    noisy, drawn so): every estimator weighs each by it. Against the same log read with one sigma
    (their RMS) the filter and the smoothers land closer, and the measurements are likelier under
    the filter (its NLL, truth-free, says which model of the noise the data prefer)."""
    from workbench.experiments.omni.readers import log

    res, _, back = paper_120
    d = back.data
    rng = np.random.default_rng(3)
    sigma = np.where(rng.random(len(d.meas_bearing)) < 0.3, 5.0, 1.0) * d.sigma_bearing
    pose, mark = d.truth[d.meas_step], d.landmarks[d.meas_lm]
    true = np.arctan2(mark[:, 1] - pose[:, 1], mark[:, 0] - pose[:, 0]) - pose[:, 2]
    bearing = np.angle(np.exp(1j * (true + rng.normal(0.0, sigma))))
    own, one = tmp_path / "own", tmp_path / "one"
    log.write(dataclasses.replace(d, meas_bearing=bearing, meas_sigma=sigma, sigma_bearing=float(np.sqrt(np.mean(
        sigma ** 2)))), own)
    shutil.copytree(own, one)
    rows = [line.split(",")[:3] for line in (own / "bearings.csv").read_text().splitlines()]
    assert (own / "bearings.csv").read_text().splitlines()[0].endswith(",sigma_rad")
    (one / "bearings.csv").write_text("\n".join(",".join(r) for r in rows) + "\n")
    a, b = _read_back(res, own), _read_back(res, one)
    assert a.data.meas_sigma is not None and b.data.meas_sigma is None
    assert a.data.sigma_bearing == pytest.approx(b.data.sigma_bearing, rel=1e-12)
    ea, eb = a.metrics["estimators"], b.metrics["estimators"]
    for name in ("ekf", "isam2", "gtsam-batch"):
        assert ea[name]["position_rmse"] < 0.9 * eb[name]["position_rmse"], (name, ea[name]["position_rmse"],
                                                                              eb[name]["position_rmse"])
    assert ea["ekf"]["nll"] < eb["ekf"]["nll"] - 100
    assert 0.9 < ea["gtsam-batch"]["bearing_residual"] < 1.1
