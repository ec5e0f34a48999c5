"""A terrain pair of your own in the open format (``docs/log-formats.md``): run 0 of the synthetic
and the real scenario written out (``--export-data``) and read back (``--scenario log --data``)
gives the same estimates; without the truth it runs; malformed folders are one line, exit 2."""

import dataclasses
import json

import numpy as np
import pytest
from launcher import DATA, bad_logs_say_one_line, cli, edit_line

import workbench

FAST = {"size": "100x100", "levels_linear": 3, "levels_angular": 2}


def _export(tmp_path, scenario: str, **settings):
    folder = tmp_path / scenario
    res = workbench.run("terrain", scenario=scenario, runs=1, export_data=folder, **settings)
    return res, folder


@pytest.mark.parametrize("scenario,settings", [
    ("synthetic", FAST),
    ("sampled", {**FAST, "hypotheses": "sample", "samples": 40}),
    ("ngi", {"levels_linear": 3, "levels_angular": 2}),
])
def test_an_exported_run_reads_back_to_the_same_estimates(tmp_path, scenario, settings):
    if scenario == "ngi" and not (DATA / "ngi").is_dir():
        pytest.skip(f"no NGI data at {DATA}")
    res, folder = _export(tmp_path, "ngi" if scenario == "ngi" else "synthetic", **settings)
    assert {p.name for p in folder.iterdir()} == {"manifest.json", "orientation.csv", "truth.csv", "dem.tif",
                                                  "image_1.tif", "image_2.tif"}
    back = workbench.run("terrain", config=dataclasses.replace(res.config, scenario="log", data=folder))
    assert np.array_equal(back.data.scene.images, res.data.scene.images)
    assert np.allclose(back.data.state, res.data.state, rtol=0, atol=1e-9)
    assert set(back.estimates) == set(res.estimates)
    for name, est in res.estimates.items():
        other = back.estimates[name]
        assert np.allclose(other.position, est.position, rtol=0, atol=1e-9), name
        assert np.allclose(other.angles, est.angles, rtol=0, atol=1e-9), name
    for name, e in res.metrics["estimators"].items():
        assert back.metrics["estimators"][name]["position_error"] == pytest.approx(e["position_error"], rel=1e-9)


def test_without_truth(tmp_path):
    res, folder = _export(tmp_path, "synthetic", **FAST)
    (folder / "truth.csv").unlink()
    out, m = tmp_path / "bare.rrd", tmp_path / "bare.json"
    r = cli("terrain", "--scenario", "log", "--data", str(folder), "--out", str(out), "--metrics", str(m),
            "--size", "100x100", "--levels-linear", "3", "--levels-angular", "2", "--radiometry", "none")
    assert r.returncode == 0, r.stderr
    stats = json.loads(m.read_text())["estimators"]
    assert stats["recurrent-search"]["position_error"] is None
    # the one truth-free verdict a pair has: each estimate against the navigation prior it fused
    for name in ("recurrent-search-posterior", "gtsam-ba"):
        assert 0 < stats[name]["prior_disagreement"] < 100 and stats[name]["consistent_without_truth"] is not None
    assert stats["navigation"].get("prior_disagreement") is None  # (the prior itself)
    assert out.stat().st_size > 0


BAD = [  # (file, how to break it, what the one line must say)
    ("manifest.json", lambda t: "not json", ["manifest.json", "not JSON"]),
    ("manifest.json", lambda t: t.replace('"fx_px"', '"f"'), ["fx_px"]),
    ("orientation.csv", lambda t: t.replace("psi_rad", "yaw"), ["orientation.csv", "missing column", "psi_rad"]),
    ("orientation.csv", lambda t: edit_line(t, 2, lambda f: [f[0], "nan", *f[2:]]),
     ["orientation.csv", "line 2", "x_m"]),
    ("orientation.csv", lambda t: edit_line(t, 3, lambda f: ["1", *f[1:]]), ["orientation.csv", "exposure 1"]),
    ("orientation.csv", lambda t: edit_line(t, 3, lambda f: ["2.5", *f[1:]]),
     ["orientation.csv", "line 3", "exposure"]),
    ("orientation.csv", lambda t: edit_line(t, 2, lambda f: [*f[:4], "9.0", *f[5:]]),
     ["orientation.csv", "line 2", "psi_rad", "beyond"]),
    ("image_2.tif", None, ["image_2.tif", "missing"]),
    ("image_1.tif", lambda t: "not an image", ["image_1.tif", "not an image"]),
    ("dem.tif", None, ["dem.tif", "missing"]),
]


def test_malformed_logs_are_one_line_and_exit_2(tmp_path):
    _, folder = _export(tmp_path, "synthetic", **FAST)
    bad_logs_say_one_line("terrain", folder, tmp_path, BAD)
