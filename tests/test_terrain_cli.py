"""``workbench terrain`` end to end: the recording read back, the metrics file, determinism,
the real NGI pair, and bad input (one line, exit code 2, nothing written)."""

import json
import shutil

import numpy as np
import pytest
from launcher import cli

from workbench.errors import WorkbenchError
from workbench.experiments.terrain import dem as dem_mod
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.readers import ngi
from workbench.paths import data_root
from workbench.recording import readback

SMALL = ("--size", "100x100", "--levels-linear", "3", "--levels-angular", "1")
NGI = data_root() / "ngi"
needs_ngi = pytest.mark.skipif(not (NGI / "dem.tif").is_file(), reason=f"no ngi data at {NGI}")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Three runs: run 0 traced in this process, runs 1-2 in forked workers after the kernel's
    threads have run (the threading layer must survive a fork)."""
    d = tmp_path_factory.mktemp("terrain")
    out, m = d / "t.rrd", d / "m.json"
    r = cli("terrain", "--runs", "3", "--seed", "4", "--out", str(out), "--metrics", str(m), *SMALL)
    assert r.returncode == 0, r.stderr
    return d, out, json.loads(m.read_text())


def test_recording_has_the_scene_the_search_and_every_estimator(recorded):
    _, out, stats = recorded
    names = ("navigation", "recurrent-search", "recurrent-search-refined", "recurrent-search-iterated",
             "recurrent-search-posterior", "gtsam-ba")
    assert set(stats["estimators"]) == set(names)
    assert stats["hypotheses"] == 27 and stats["nodes"] > 1000
    rows = readback.row_counts(out)
    assert rows["/functional"] == 27                       # one functional per hypothesis
    assert rows["/world/search/hypotheses"] >= 1           # one row per evaluated chunk
    static = readback.row_counts(out, temporal_only=False)
    for path in ("/world/dem", "/world/cameras/truth/I", "/world/cameras/truth/II", "/world/search/winner",
                 "/world/ba/tie_points", "/world/ba/rays", "/orthophoto", "/summary"):
        assert static[path] >= 1, path
    for name in names:
        assert static[f"/world/halftone/{name}"] >= 1 and static[f"/errors/{name}"] >= 1, name
        assert static[f"/world/cameras/{name}/II"] >= 1, name
    props = readback.properties(out)
    assert props["experiment"] == "terrain" and int(props["seed"]) == 4


def test_metrics_file_shape_and_reduction(recorded):
    _, _, stats = recorded
    assert stats["experiment"] == "terrain" and stats["mode"] == "common" and stats["runs"] == 3
    for e in stats["estimators"].values():
        for key in ("position_error", "attitude_error", "ground_rmse", "seconds", "reduction", "paper"):
            assert key in e
    est = stats["estimators"]
    assert est["navigation"]["reduction"] == pytest.approx(1.0, abs=1e-12)
    assert est["recurrent-search-refined"]["anees"] > 0 and len(est["recurrent-search-refined"]["nees_band"]) == 2
    # even a 3-level grid (67 m cells) with the refinement beats the navigation system by far
    assert est["recurrent-search-refined"]["position_error"] < 0.5 * est["navigation"]["position_error"]
    assert est["recurrent-search-refined"]["ground_rmse"] < 0.5 * est["navigation"]["ground_rmse"]


def test_same_seed_same_numbers(recorded, tmp_path):
    _, _, stats = recorded
    m = tmp_path / "m.json"
    r = cli("terrain", "--runs", "3", "--seed", "4", "--out", str(tmp_path / "t.rrd"), "--metrics", str(m),
            "--estimators", "recurrent-search,recurrent-search-refined", *SMALL)
    assert r.returncode == 0, r.stderr
    again = json.loads(m.read_text())
    for name in ("navigation", "recurrent-search", "recurrent-search-refined"):
        assert again["estimators"][name]["position_error"] == stats["estimators"][name]["position_error"]


def test_no_overwrite_without_force(recorded):
    d, out, _ = recorded
    before = out.stat().st_mtime_ns
    r = cli("terrain", "--out", str(out), *SMALL)
    assert r.returncode == 2 and "exists" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert out.stat().st_mtime_ns == before


@pytest.mark.parametrize("args, message", [
    (("--max-linear", "0"), "--max-linear must be a positive number"),
    (("--max-angular", "-0.001"), "--max-angular must be a positive number"),
    (("--size", "abc"), "--size must look like WIDTHxHEIGHT"),
    (("--size", "8x8"), "at least 16x16"),
    (("--mode", "both"), "unknown error mode"),
    (("--scenario", "ngi", "--size", "200x200", "--data", "."), "does not keep the ngi frames' aspect"),
    (("--scenario", "ngi", "--size", "660x1188", "--data", "."), "larger than the ngi frames"),
    (("--scenario", "ngi", "--data", "/nonexistent/ngi"), "ngi data folder not found"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, message):
    if "--data" in args and "." in args:  # a folder that exists but is checked after the size
        args = tuple(str(tmp_path) if a == "." else a for a in args)
    out = tmp_path / "t.rrd"
    r = cli("terrain", "--out", str(out), *args)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert not out.exists()


def test_dem_that_does_not_cover_the_footprint():
    from workbench.experiments.terrain import camera

    tiny = dem_mod.Dem(np.zeros((5, 5)), -50.0, -50.0, 25.0, 25.0)
    k = camera.Intrinsics(100.0, 100.0, 49.5, 49.5, 100, 100)
    with pytest.raises(WorkbenchError, match="the DEM does not cover"):
        camera.ground_points(tiny, k, np.array([0.0, 0.0, 1000.0]), camera.rotation(np.zeros(3)),
                             *k.pixel_grid(10))


def test_corrupt_tiff_is_a_one_line_error(tmp_path):
    bad = tmp_path / "dem.tif"
    bad.write_bytes(b"II*\x00\xff\xff\xff\x00garbage")
    with pytest.raises(WorkbenchError, match="corrupt TIFF"):
        dem_mod.read_geotiff(bad)
    bad.write_bytes(b"not a tiff at all")
    with pytest.raises(WorkbenchError, match="not a TIFF"):
        dem_mod.read_geotiff(bad)


@needs_ngi
def test_real_dem_placement_from_geotiff_tags():
    d = dem_mod.read_geotiff(NGI / "dem.tif")
    assert d.heights.shape == (508, 327)
    assert 140 < np.nanmin(d.heights) < 160 and 770 < np.nanmax(d.heights) < 790
    assert d.dy < 0 and 20 < d.dx < 30
    x0, x1, y0, y1 = d.extent
    for frame in ("0182", "0184", "0251", "0253"):   # every frame's projection centre is over the DEM
        pos = ngi.read_orientation(NGI / "camera_pos_ori.txt")[frame][0]
        assert x0 < pos[0] < x1 and y0 < pos[1] < y1


@needs_ngi
def test_ngi_bad_folders(tmp_path):
    """A corrupt DEM and an orientation file with a missing frame, through the launcher."""
    for f in NGI.iterdir():
        shutil.copy(f, tmp_path / f.name)
    (tmp_path / "dem.tif").chmod(0o644)
    (tmp_path / "dem.tif").write_bytes((NGI / "dem.tif").read_bytes()[:3000])
    r = cli("terrain", "--scenario", "ngi", "--data", str(tmp_path), "--out", str(tmp_path / "a.rrd"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "DEM" in r.stderr or "TIFF" in r.stderr
    shutil.copy(NGI / "dem.tif", tmp_path / "dem.tif")
    orient = tmp_path / "camera_pos_ori.txt"
    orient.chmod(0o644)
    orient.write_text("\n".join(line for line in (NGI / "camera_pos_ori.txt").read_text().splitlines()
                                if "0184" not in line))
    r = cli("terrain", "--scenario", "ngi", "--data", str(tmp_path), "--out", str(tmp_path / "b.rrd"))
    assert r.returncode == 2 and "no frame 0184" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@needs_ngi
def test_ngi_truth_is_photo_consistent():
    """The known orientation is the truth: image I warped into image II through the DEM fits
    better at it than 50 m away (the check that the OPK convention is read right)."""
    from workbench.experiments.terrain.algorithms import search

    cfg = TerrainConfig(scenario="ngi", size="160x288", mode="ii-only").validate()
    sc = ngi.load(cfg)
    p = search.make_problem(cfg, sc.k, sc.dem, sc.position, sc.angles, sc.images, sc.interval)
    r_true, _ = search.linearise(p, np.zeros((1, 6)))
    r_off, _ = search.linearise(p, np.array([[50.0, 0, 0, 0, 0, 0], [0, 0, 0, 50.0, 0, 0]]))
    assert np.sqrt(np.mean(r_true ** 2)) < 0.75 * np.sqrt(np.mean(r_off ** 2, axis=1)).min()
