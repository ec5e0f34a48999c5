"""The launcher end to end: recordings read back, metrics, bad input, determinism."""

import json
import os

import pytest
from launcher import DATA, cli, wb

from workbench.recording import readback

ALL = ("geometric", "rls", "window-rls", "ekf", "gtsam", "isam2")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    out, m = d / "sea.rrd", d / "m.json"
    r = cli("sea", "--runs", "3", "--seed", "7", "--out", str(out), "--metrics", str(m), "--duration", "20")
    assert r.returncode == 0, r.stderr
    return out, json.loads(m.read_text())


def test_recording_has_every_estimator(recorded):
    out, stats = recorded
    rows = readback.row_counts(out)
    T = stats["steps"]
    assert T == 201
    for name in ALL:
        assert rows[f"/map/{name}/position"] == T, name
        for q in ("x", "y", "alpha", "beta"):
            assert rows[f"/errors/{q}/{name}"] == T, (name, q)
        assert rows[f"/series/alpha/{name}"] == T
        assert rows[f"/monte_carlo/position_rmse/{name}"] == T
    assert rows["/map/ekf/ellipse"] == T and rows["/map/gtsam/ellipse"] == T
    assert rows["/map/line_of_sight"] == T
    assert rows["/monte_carlo/nees/ekf"] == T
    props = readback.properties(out)
    assert props["experiment"] == "sea" and int(props["seed"]) == 7
    assert json.loads(props["config"])["runs"] == 3


def test_metrics_file_shape(recorded):
    _, stats = recorded
    assert stats["experiment"] == "sea" and stats["scenario"] == "paper" and stats["runs"] == 3
    for name in ALL:
        e = stats["estimators"][name]
        for key in ("rmse", "bias"):
            assert set(e[key]) >= {"x", "y", "alpha", "beta"}
        assert e["seconds"] > 0


def test_same_seed_same_numbers(tmp_path, recorded):
    _, stats = recorded
    m = tmp_path / "m.json"
    r = cli("sea", "--runs", "3", "--seed", "7", "--out", str(tmp_path / "a.rrd"), "--metrics", str(m),
            "--duration", "20")
    assert r.returncode == 0, r.stderr
    again = json.loads(m.read_text())
    for name in ALL:
        assert again["estimators"][name]["rmse"] == stats["estimators"][name]["rmse"]


def _malformed_ais(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("Time,MMSI,Latitude_degrees\n2016-01-12 13:02:11,1,50.7\n")
    return str(p)


@pytest.mark.parametrize("args,needle", [
    (["--runs", "0"], "--runs"),
    (["--sigma-alpha", "-1"], "negative"),
    (["--lam", "1.5"], "--lam"),
    (["--lam", "0"], "--lam"),
    (["--window", "3"], "--window"),
    (["--scenario", "ais", "--data", "/nonexistent/ais.csv"], "not found"),
    (["--scenario", "ais", "--data", "MALFORMED"], "malformed"),
    (["--scenario", "nowhere"], "scenario"),
])
def test_bad_input_one_line_exit_2(tmp_path, args, needle):
    args = [_malformed_ais(tmp_path) if a == "MALFORMED" else a for a in args]
    out = tmp_path / "x.rrd"
    r = cli("sea", "--out", str(out), *args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.stderr
    assert not out.exists()


@pytest.mark.skipif(not (DATA / "ais").is_dir(), reason="real AIS data not present")
def test_unknown_mmsi(tmp_path):
    r = cli("sea", "--scenario", "ais", "--mmsi", "1", "--out", str(tmp_path / "x.rrd"))
    assert r.returncode == 2 and "unknown MMSI" in r.stderr


def test_existing_output_not_overwritten(tmp_path):
    out = tmp_path / "keep.rrd"
    out.write_bytes(b"precious")
    r = cli("sea", "--out", str(out), "--duration", "5")
    assert r.returncode == 2 and "--force" in r.stderr
    assert out.read_bytes() == b"precious"


def test_unwritable_path(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        if os.access(locked, os.W_OK):
            pytest.skip("running as a user who can write anywhere (root)")
        r = cli("sea", "--out", str(locked / "x.rrd"), "--duration", "5")
        assert r.returncode == 2 and "cannot write" in r.stderr
    finally:
        locked.chmod(0o700)


def test_unwritable_path_under_a_file(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = cli("sea", "--out", str(blocker / "x.rrd"), "--duration", "5")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1


def test_list_names_experiments():
    r = wb("list")
    assert r.returncode == 0
    names = [line.split()[0] for line in r.stdout.splitlines() if not line.startswith(" ")]
    assert names == ["omni", "sea", "terrain"]
    assert "  estimators: geometric, rls, window-rls, ekf, gtsam, isam2" in r.stdout
