"""A sea log of your own in the open format (``docs/log-formats.md``): any scenario's run 0 written
out (``--export-data``) and read back (``--scenario log --data``) gives the same estimates; a log
without its truth, or with a sparse one, runs and is scored where it can be; malformed logs are
one line naming the file, the line and the column, exit 2, nothing written."""

import json
import shutil

import numpy as np
import pytest
from launcher import DATA, bad_logs_say_one_line, cli, edit_line

import workbench
from workbench.io import csvfiles as csvfile
from workbench.recording import blueprints, readback

ALL = "geometric,rls,window-rls,ekf,gtsam,isam2,fixed-lag"


def _export(tmp_path, scenario: str, estimators: str = ALL, **settings):
    """Run 0 of ``scenario`` and its dataset written out (the data do not depend on the estimators:
    a test that reads only some estimates runs only those)."""
    folder = tmp_path / scenario
    res = workbench.run("sea", scenario=scenario, runs=1, estimators=estimators, export_data=folder, **settings)
    return res, folder


@pytest.mark.parametrize("scenario", ["paper", "impulse", "track-loss", "ais"])
def test_an_exported_run_reads_back_to_the_same_estimates(tmp_path, scenario):
    if scenario == "ais" and not (DATA / "ais").is_dir():
        pytest.skip(f"no AIS data at {DATA}")
    settings = {"tune_noise": False} if scenario == "ais" else {"duration": 30.0}   # the log holds the data's noise
    res, folder = _export(tmp_path, scenario, **settings)
    assert {p.name for p in folder.iterdir()} == {"manifest.json", "observer.csv", "angles.csv", "truth.csv"}
    back = workbench.run("sea", scenario="log", data=folder, runs=1, estimators=ALL)
    for name, est in res.estimates.items():
        assert np.allclose(back.estimates[name].position, est.position, rtol=0, atol=1e-9, equal_nan=True), name
    for name, e in res.metrics["estimators"].items():
        assert back.metrics["estimators"][name]["position_rmse"] == pytest.approx(e["position_rmse"], rel=1e-9)


def test_without_truth_and_with_a_sparse_one(tmp_path):
    res, folder = _export(tmp_path, "paper", "geometric,ekf,gtsam", duration=30.0)
    bare = tmp_path / "bare"
    shutil.copytree(folder, bare)
    (bare / "truth.csv").unlink()
    out, m = tmp_path / "bare.rrd", tmp_path / "bare.json"
    r = cli("sea", "--scenario", "log", "--data", str(bare), "--out", str(out), "--metrics", str(m))
    assert r.returncode == 0, r.stderr
    stats = json.loads(m.read_text())
    ekf = stats["estimators"]["ekf"]
    assert ekf["position_rmse"] is None and ekf["anees"] is None and ekf["consistent_without_truth"] is True
    # the recording's reference is the smoother: each estimate's departure from it, named so
    names = [v.name for v in blueprints.layout(out).views()]
    assert "departure from gtsam (m): filters" in names and not any(n.startswith("position error") for n in names)
    t, x = readback.series(out, "/errors/x/ekf")
    assert len(t) == len(res.data.t)
    assert np.allclose(x, res.estimates["gtsam"].position[:, 0] - res.estimates["ekf"].position[:, 0], atol=1e-9)
    assert ekf["nis"] == pytest.approx(res.metrics["estimators"]["ekf"]["nis"], rel=1e-9)  # it never read the truth
    # a sparse truth (a fix every 2 s): the errors at those times alone
    sparse = tmp_path / "sparse"
    shutil.copytree(folder, sparse)
    lines = (folder / "truth.csv").read_text().splitlines()
    (sparse / "truth.csv").write_text("\n".join([lines[0], *lines[1::20]]) + "\n")
    back = workbench.run("sea", scenario="log", data=sparse, runs=1, estimators="geometric,ekf")
    steps = np.arange(0, len(res.data.t), 20)
    for name in ("geometric", "ekf"):
        e = res.data.target[steps, :2] - res.estimates[name].position[steps]
        want = np.sqrt(np.nanmean(np.sum(e**2, axis=1)))
        assert back.metrics["estimators"][name]["position_rmse"] == pytest.approx(want, rel=1e-12), name


def test_the_observer_in_latitude_and_longitude(tmp_path):
    res, folder = _export(tmp_path, "paper", "geometric", duration=20.0)
    rows = np.loadtxt(folder / "observer.csv", delimiter=",", skiprows=1)
    lat0, lon0 = 50.8, -1.3
    lat = lat0 + np.degrees(rows[:, 2] / csvfile.EARTH_RADIUS)
    lon = lon0 + np.degrees(rows[:, 1] / (csvfile.EARTH_RADIUS * np.cos(np.radians(lat0))))
    shift = csvfile.to_local(lat[:1], lon[:1], lat0, lon0)[0]   # the log's frame is centred on its first fix
    text = "t_s,lat_deg,lon_deg,vx_mps,vy_mps,course_rad\n" + "".join(
        ",".join(repr(float(v)) for v in (r[0], a, o, r[3], r[4], r[5])) + "\n" for r, a, o in zip(rows, lat, lon,
                                                                                              strict=True))
    (folder / "observer.csv").write_text(text)
    (folder / "truth.csv").unlink()
    back = workbench.run("sea", scenario="log", data=folder, runs=1, estimators="geometric")
    moved = res.estimates["geometric"].position - shift
    assert np.allclose(back.estimates["geometric"].position, moved, atol=1e-6)


BAD = [  # (file, how to break it, what the one line must say)
    ("manifest.json", lambda t: "not json", ["manifest.json", "not JSON"]),
    ("manifest.json", lambda t: t.replace('"height_m": 3.0', '"height_m": -3.0'), ["height_m"]),
    ("manifest.json", lambda t: t.replace('"sigma_azimuth_rad"', '"sigma_az"'), ["sigma_azimuth_rad"]),
    ("manifest.json", lambda t: t.replace('"dt_s": 0.1', '"dt_s": "fast"'), ["dt_s"]),
    ("observer.csv", lambda t: "", ["observer.csv", "no header"]),
    ("observer.csv", lambda t: t.splitlines()[0] + "\n", ["observer.csv", "no rows"]),
    ("observer.csv", lambda t: t.replace("course_rad", "heading"), ["observer.csv", "missing column", "course_rad"]),
    ("observer.csv", lambda t: t.replace("x_m,y_m", "east,north"), ["observer.csv", "x_m, y_m"]),
    ("observer.csv", lambda t: edit_line(t, 5, lambda f: [f[0], "nan", *f[2:]]), ["observer.csv", "line 5", "x_m"]),
    ("observer.csv", lambda t: edit_line(t, 5, lambda f: [f[0], "inf", *f[2:]]), ["observer.csv", "line 5", "x_m"]),
    ("observer.csv", lambda t: edit_line(t, 6, lambda f: [f[0], "1e3x", *f[2:]]), ["observer.csv", "line 6", "x_m"]),
    ("observer.csv", lambda t: edit_line(t, 5, lambda f: ["0.4321", *f[1:]]), ["observer.csv", "line 5", "t_s",
                                                                          "off the uniform step"]),
    ("observer.csv", lambda t: edit_line(t, 30, lambda f: ["-9.0", *f[1:]]), ["observer.csv", "line 30", "backwards"]),
    ("angles.csv", lambda t: t.replace("azimuth_rad", "bearing"), ["angles.csv", "missing column", "azimuth_rad"]),
    ("angles.csv", lambda t: edit_line(t, 4, lambda f: [f[0], "3.5", f[2]]), ["angles.csv", "line 4", "azimuth_rad",
                                                                         "beyond"]),
    ("angles.csv", lambda t: edit_line(t, 4, lambda f: [f[0], f[1], "2.0"]), ["angles.csv", "line 4", "elevation_rad"]),
    ("angles.csv", lambda t: edit_line(t, 4, lambda f: ["0.3333", *f[1:]]), ["angles.csv", "line 4", "t_s",
                                                                        "not a time of the observer"]),
    ("angles.csv", lambda t: edit_line(t, 4, lambda f: [f[0], "", f[2]]), ["angles.csv", "line 4", "azimuth_rad"]),
    ("truth.csv", lambda t: t.splitlines()[0] + "\n1000.0,1,2,3,4,5,6\n", ["truth.csv", "covers none of the run"]),
    ("truth.csv", lambda t: t.replace("vx_mps", "speed"), ["truth.csv", "missing column", "vx_mps"]),
]


def test_malformed_logs_are_one_line_and_exit_2(tmp_path):
    _, folder = _export(tmp_path, "paper", "geometric", duration=10.0)
    bad_logs_say_one_line("sea", folder, tmp_path, BAD)
