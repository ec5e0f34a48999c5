"""Config files (``--config FILE``): a recording's stored config runs as it is, a TOML file of the
options' names sets what the options set, the command line wins over the file and the file over
the scenario's defaults; a bad file is one line naming the key."""

import json

import numpy as np
import pytest
from launcher import cli

import workbench


def test_a_recordings_stored_config_runs_again_the_same(tmp_path):
    first = tmp_path / "a.rrd"
    r = cli("sea", "--runs", "2", "--duration", "20", "--sigma-acc", "0.3", "--order", "3", "--estimators",
            "ekf,gtsam,rls", "--out", str(first), "--metrics", str(tmp_path / "a.json"))
    assert r.returncode == 0, r.stderr
    shown = cli("info", str(first), "--config")
    assert shown.returncode == 0, shown.stderr
    (tmp_path / "c.json").write_text(shown.stdout)
    stored = json.loads(shown.stdout)
    assert stored["sigma_acc"] == 0.3 and stored["order_alpha"] == 3 and stored["runs"] == 2
    again = cli("sea", "--config", str(tmp_path / "c.json"), "--out", str(tmp_path / "b.rrd"),
                "--metrics", str(tmp_path / "b.json"))
    assert again.returncode == 0, again.stderr
    a, b = (json.loads((tmp_path / f"{n}.json").read_text()) for n in "ab")
    assert list(b["estimators"]) == ["ekf", "gtsam", "rls"]
    for name in a["estimators"]:
        for key in ("position_rmse", "nis", "angle_residual"):
            assert a["estimators"][name].get(key) == b["estimators"][name].get(key), (name, key)


def test_a_toml_file_sets_what_the_options_set_and_the_options_win():
    path_free = {"sigma-acc": 0.3, "order": 3, "duration": 20.0, "runs": 2, "image-size": "640x480"}
    by_file = workbench.configure("sea", config=path_free)
    by_options = workbench.configure("sea", sigma_acc=0.3, order_alpha=3, order_beta=3, duration=20.0, runs=2,
                                     image_size=(640, 480))
    assert by_file == by_options
    over = workbench.configure("sea", config=path_free, sigma_acc=0.5)          # the options on top
    assert over.sigma_acc == 0.5 and over.order_beta == 3
    # the file's scenario where none is given; its explicit values over the scenario's defaults
    scen = workbench.configure("sea", config={"scenario": "impulse", "duration": 10.0})
    assert scen.scenario == "impulse" and scen.duration == 10.0
    assert workbench.configure("sea", "track-loss", config={"scenario": "impulse"}).scenario == "track-loss"


def test_the_same_run_from_a_file_and_from_options(tmp_path):
    (tmp_path / "omni.toml").write_text('duration = 40.0\nsigma-v = 0.2\nestimators = ["ekf", "isam2"]\n')
    a = workbench.run("omni", config=tmp_path / "omni.toml")
    b = workbench.run("omni", duration=40.0, sigma_v=0.2, estimators=["ekf", "isam2"])
    assert set(a.estimates) == {"ekf", "isam2"} and a.config.sigma_v == 0.2
    for name in a.estimates:
        assert np.array_equal(a.estimates[name].pose, b.estimates[name].pose), name


@pytest.mark.parametrize("text,suffix,said", [
    ("foo = 1\n", "toml", "c.toml: foo: sea has no such setting"),
    ('sigma-acc = "fast"\n', "toml", "c.toml: sigma-acc: must be a number, got 'fast'"),
    ("runs = 2.5\n", "toml", "c.toml: runs: must be a whole number, got 2.5"),
    ("target_start = [1.0]\n", "toml", "c.toml: target_start: must be a list of 2"),
    ("robust = 1\n", "toml", "c.toml: robust: must be true or false, got 1"),
    ("[sea]\nlam = 1\n", "toml", "c.toml: sea: a table; a config file is flat"),
    ("lam = [\n", "toml", "c.toml: not TOML"),
    ('{"lam": 0.9,}', "json", "c.json: not JSON"),
    ("[1, 2]", "json", "the file must hold a table of key = value, not a list"),
    ("lam = 3\n", "toml", "--lam must be in (0, 1], got 3.0"),
    ("lam = 1\n", "yaml", "a config file is .toml or .json"),
])
def test_a_bad_file_is_one_line_naming_the_key(tmp_path, text, suffix, said):
    (tmp_path / f"c.{suffix}").write_text(text)
    r = cli("sea", "--config", str(tmp_path / f"c.{suffix}"), "--out", str(tmp_path / "x.rrd"))
    assert r.returncode == 2 and said in r.stderr, r.stderr
    assert "\n" not in r.stderr.strip() and "Traceback" not in r.stderr
    assert not (tmp_path / "x.rrd").exists()


def test_a_sweep_takes_a_config_file_beneath_its_grid(tmp_path):
    (tmp_path / "s.toml").write_text('sigma-acc = 0.2\nlam = 0.5\nruns = 2\nduration = 20.0\n'
                                     'estimators = ["ekf", "gtsam"]\n')
    r = cli("sweep", "sea", "--config", str(tmp_path / "s.toml"), "--grid", "lam=0.9,1", "--out",
            str(tmp_path / "sw"), "--jobs", "1")
    assert r.returncode == 0, r.stderr
    manifest = json.loads((tmp_path / "sw" / "sweep.json").read_text())
    assert manifest["fixed"] == {"sigma_acc": 0.2, "duration": 20.0}   # the grid sets lam
    assert manifest["runs"] == 2 and manifest["estimators"] == ["ekf", "gtsam"]
    assert manifest["grid"]["lam"] == [0.9, 1.0]
