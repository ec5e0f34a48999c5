"""Your own estimator beside the paper's, through every path a user takes: a ``file.py:function``
spec on the command line, a function through the Python API, an installed entry point.

The known-offset plugins (the truth moved by a fixed amount) must come out with exactly that
offset as their RMSE, in every experiment; a plugin that raises or breaks its estimate type is
named in one line, the other estimators' results are still written, and the exit code is 3.
"""

import json
import math
import textwrap

import numpy as np
import pytest
from launcher import cli, wb

import workbench
from workbench.core import estimator as plugins
from workbench.core.registry import get
from workbench.errors import WorkbenchError
from workbench.experiments.sea.estimate import Estimate as SeaEstimate
from workbench.recording import readback

PLUGIN = textwrap.dedent('''
    import numpy as np

    import workbench
    from workbench.experiments.omni.estimate import SlamEstimate
    from workbench.experiments.sea.estimate import Estimate as SeaEstimate
    from workbench.experiments.terrain.estimate import Estimate as TerrainEstimate


    @workbench.estimator(description="the truth plus (3, -4) m", causal=True, covariances=True)
    def sea_offset(data, cfg):
        T = data.steps
        return SeaEstimate(position=data.target[:, :2] + [3.0, -4.0],
                           covariance=np.broadcast_to(np.eye(2), (T, 2, 2)).copy())


    def omni_offset(data, cfg):
        return SlamEstimate(pose=data.truth + [0.3, -0.4, 0.01])


    def terrain_offset(data, cfg):
        sc = data.scene
        return TerrainEstimate(position=sc.position + [[0.0, 0.0, 0.0], [3.0, -4.0, 12.0]], angles=sc.angles.copy())


    def raises(data, cfg):
        raise RuntimeError("deliberately broken")


    def flaky(data, cfg, ctx):
        if ctx.run == 2:
            raise ValueError("run two is bad")
        return SeaEstimate(position=data.target[:, :2].copy())


    def wrong_shape(data, cfg):
        return SeaEstimate(position=np.zeros((3, 2)))


    def partly_nan(data, cfg):
        p = data.target[:, :2].copy()
        p[5, 0] = np.nan
        return SeaEstimate(position=p)


    def not_psd(data, cfg):
        return SeaEstimate(position=data.target[:, :2].copy(),
                           covariance=np.broadcast_to(np.diag([1.0, -1.0]), (data.steps, 2, 2)).copy())


    def not_an_estimate(data, cfg):
        return {"position": data.target[:, :2]}


    def sleeps_forever(data, cfg):
        import time

        while True:
            time.sleep(3600)
''')
SEA = ("--duration", "20")
OMNI = ("--duration", "40")
TERRAIN = ("--size", "100x100", "--levels-linear", "3", "--levels-angular", "1")


@pytest.fixture(scope="module")
def plugin(tmp_path_factory):
    path = tmp_path_factory.mktemp("plugin") / "my_filters.py"
    path.write_text(PLUGIN)
    return path


def _run(tmp_path, experiment, *args):
    out, m = tmp_path / "r.rrd", tmp_path / "m.json"
    r = cli(experiment, "--out", str(out), "--metrics", str(m), *args)
    return r, out, (json.loads(m.read_text()) if m.exists() else None)


def test_sea_offset_is_its_rmse_everywhere(tmp_path, plugin):
    """Three runs (two through the worker pool): RMSE x 3, y 4, position 5, to round-off; the
    plugin in the table, the metrics, the recording (its colour, its ellipses, its curves)."""
    r, out, stats = _run(tmp_path, "sea", "--runs", "3", *SEA, "--estimators", f"geometric,{plugin}:sea_offset")
    assert r.returncode == 0, r.stderr
    e = stats["estimators"]["sea_offset"]
    assert e["rmse"]["x"] == pytest.approx(3.0, rel=1e-12) and e["rmse"]["y"] == pytest.approx(4.0, rel=1e-12)
    assert e["bias"]["x"] == pytest.approx(-3.0, rel=1e-12) and e["position_rmse"] == pytest.approx(5.0, rel=1e-12)
    assert e["rmse_std"]["x"] < 1e-12 and e["coverage"] == 1.0
    table = stats["estimator_table"]["sea_offset"]
    assert table["description"] == "the truth plus (3, -4) m" and table["causal"] and table["source"].endswith(
        "my_filters.py:sea_offset")
    assert "| sea_offset |" in r.stdout
    T = stats["steps"]
    rows = readback.row_counts(out)
    for path in ("/map/sea_offset/position", "/map/sea_offset/ellipse", "/errors/x/sea_offset",
                 "/series/alpha/sea_offset", "/monte_carlo/position_rmse/sea_offset"):
        assert rows[path] == T, path
    ours = readback.rgb(readback.static_values(out, "/errors/x/sea_offset", "SeriesLines:colors")[0])
    builtin = readback.rgb(readback.static_values(out, "/errors/x/geometric", "SeriesLines:colors")[0])
    assert ours == tuple(table["color"]) and ours != builtin
    widths = [readback.static_values(out, f"/errors/x/{n}", "SeriesLines:widths")[0]
              for n in ("sea_offset", "geometric")]
    assert widths[0] > widths[1]  # the researcher's own estimator drawn wider than the built-ins
    t, curve = readback.series(out, "/monte_carlo/position_rmse/sea_offset")
    assert np.allclose(curve, 5.0)
    assert json.loads(readback.properties(out)["config"])["estimators"][1].startswith("sea_offset=")


def test_omni_offset_is_its_rmse(tmp_path, plugin):
    r, out, stats = _run(tmp_path, "omni", "--runs", "2", *OMNI, "--settle", "0",
                         "--estimators", f"odometry,{plugin}:omni_offset")
    assert r.returncode == 0, r.stderr
    e = stats["estimators"]["omni_offset"]
    assert e["rmse"]["position"] == pytest.approx(0.5, rel=1e-12)
    assert e["rmse"]["heading"] == pytest.approx(math.degrees(0.01), rel=1e-9)
    assert e["coverage"] == 1.0 and e["rmse"]["map"] is None
    rows = readback.row_counts(out)
    assert rows["/map/omni_offset/vehicle"] == stats["grid_steps"] == rows["/errors/position/omni_offset"]


def test_terrain_offset_is_its_error(tmp_path, plugin):
    """The navigation reference is added (every reduction is against it); image II's error is
    the offset: 13 m, RMSE x 3, y 4, h 12."""
    r, out, stats = _run(tmp_path, "terrain", "--runs", "2", *TERRAIN, "--estimators", f"{plugin}:terrain_offset")
    assert r.returncode == 0, r.stderr
    assert list(stats["estimators"]) == ["navigation", "terrain_offset"]
    e = stats["estimators"]["terrain_offset"]
    assert e["position_error"] == pytest.approx(13.0, rel=1e-12) and e["attitude_error"] < 1e-12
    assert e["rmse"] == pytest.approx({"x": 3.0, "y": 4.0, "h": 12.0}, rel=1e-12)
    static = readback.row_counts(out, temporal_only=False)
    assert static["/world/cameras/terrain_offset/II"] >= 1 and static["/errors/terrain_offset"] >= 1


def _offset(data, cfg):
    """The truth plus (1, 2) m."""
    return SeaEstimate(position=data.target[:, :2] + [1.0, 2.0])


def test_python_api_with_a_function(tmp_path):
    res = workbench.run("sea", runs=3, duration=10.0, estimators=["geometric", _offset], out=tmp_path / "a.rrd")
    e = res.metrics["estimators"]["_offset"]
    assert e["rmse"]["x"] == pytest.approx(1.0, rel=1e-12) and e["rmse"]["y"] == pytest.approx(2.0, rel=1e-12)
    assert res.metrics["estimator_table"]["_offset"]["description"] == "The truth plus (1, 2) m."
    assert set(res.estimates) == {"geometric", "_offset"} and res.data.steps == 101
    assert res.recording.is_file() and not res.failures
    # alpha, beta and range were derived from the position (the camera at the measured observer)
    assert np.isfinite(res.estimates["_offset"].alpha).all()


def test_a_failing_plugin_is_named_and_the_rest_is_written(tmp_path, plugin):
    r, out, stats = _run(tmp_path, "sea", "--runs", "2", *SEA, "--estimators", f"geometric,ekf,{plugin}:raises")
    assert r.returncode == 3
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "'raises'" in lines[0] and "deliberately broken" in lines[0], r.stderr
    assert set(stats["estimators"]) == {"geometric", "ekf"} and "raises" in stats["failed"]
    rows = readback.row_counts(out)
    assert rows["/map/ekf/position"] == stats["steps"] and "/map/raises/position" not in rows


def test_a_plugin_failing_in_a_later_run_is_left_out_of_every_run(tmp_path, plugin):
    r, out, stats = _run(tmp_path, "sea", "--runs", "4", *SEA, "--estimators", f"geometric,{plugin}:flaky")
    assert r.returncode == 3 and "run two is bad (run 2)" in r.stderr
    assert set(stats["estimators"]) == {"geometric"} and "/map/flaky/position" not in readback.row_counts(out)


@pytest.mark.parametrize("name, needle", [
    ("wrong_shape", "position has shape (3, 2), expected (201, 2)"),
    ("partly_nan", "position is partly NaN at row 5"),
    ("not_psd", "covariance is not positive semi-definite"),
    ("not_an_estimate", "returned dict, not a sea Estimate"),
])
def test_a_broken_estimate_is_named(tmp_path, plugin, name, needle):
    r, _, stats = _run(tmp_path, "sea", *SEA, "--estimators", f"geometric,{plugin}:{name}")
    assert r.returncode == 3 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert list(stats["estimators"]) == ["geometric"]


@pytest.mark.parametrize("spec, needle", [
    ("nosuch_module_xyz:fn", "cannot import estimator module 'nosuch_module_xyz'"),
    ("PLUGIN:missing", "has no 'missing'"),
    ("/nonexistent/f.py:fn", "estimator file not found"),
    ("magic", "unknown estimator 'magic' for sea"),
    ("geometric,geometric", "selected twice"),
    ("bad name=PLUGIN:raises", "estimator file not found"),
])
def test_bad_specs_are_one_line_and_exit_2(tmp_path, plugin, spec, needle):
    r, out, _ = _run(tmp_path, "sea", *SEA, "--estimators", spec.replace("PLUGIN", str(plugin)))
    assert r.returncode == 2 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not out.exists()


def test_named_specs_and_the_defaults_plus(plugin):
    exp = get("sea")
    chosen = exp.select(f"+mine={plugin}:sea_offset")
    assert [e.name for e in chosen] == [*exp.default_estimators, "mine"]
    assert chosen[-1].color not in [e.color for e in chosen[:-1]]
    with pytest.raises(WorkbenchError, match="selected twice"):
        exp.select(["ekf", "ekf"])


def test_installed_entry_points_are_found():
    """The package registers its own extra estimators the way a user's package would."""
    for experiment in ("sea", "omni"):
        assert "fixed-lag" in plugins.installed(experiment)
        est = get(experiment).select(["fixed-lag"])[0]
        assert est.source.startswith(f"entry point {experiment}.fixed-lag") and est.causal and est.covariances


def test_a_dataset_and_estimators_by_hand():
    """The contract's pieces for a notebook: run k's dataset (the same for the same seed) and
    the chosen estimators on it, checked and timed."""
    exp = workbench.experiment("omni")
    cfg = workbench.configure("omni", duration=20.0)
    data = exp.dataset(cfg, 3)
    again, other = exp.dataset(cfg, 3), exp.dataset(cfg, 4)
    assert np.array_equal(data.controls, again.controls) and np.array_equal(data.meas_bearing, again.meas_bearing)
    assert not np.array_equal(data.controls, other.controls)
    est, failed = exp.estimate(data, cfg, ["odometry", "ekf"])
    assert not failed and list(est) == ["odometry", "ekf"] and len(est["ekf"].steps) == len(data.t)
    assert all(e.seconds > 0 for e in est.values())


# --- an estimator that never returns (issue 27 item 3) ----------------------------------------------

def test_an_estimator_that_never_returns_costs_one_estimator(tmp_path, plugin):
    """``--estimator-timeout 2`` and a plugin asleep for ever, over 4 runs on two processes: the
    run ends in bounded time (2 s once: the workers forked after run 0 know it timed out), exit 3,
    one line naming it and saying it timed out; the others' metrics and recording are written."""
    import time

    t0 = time.monotonic()
    r, out, stats = _run(tmp_path, "sea", "--runs", "4", "--jobs", "2", *SEA, "--estimator-timeout", "2",
                         "--estimators", f"geometric,ekf,{plugin}:sleeps_forever")
    took = time.monotonic() - t0
    assert r.returncode == 3, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "'sleeps_forever'" in lines[0] and "timed out after 2 s" in lines[0], r.stderr
    assert set(stats["estimators"]) == {"geometric", "ekf"} and "timed out" in stats["failed"]["sleeps_forever"]
    assert stats["runs"] == 4 and stats["config"]["estimator_timeout"] == 2.0
    assert readback.row_counts(out)["/map/ekf/position"] == stats["steps"]
    assert took < 60, f"{took:.0f} s"  # ~6 s here; without the limit: never


def test_a_timeout_stops_a_python_loop_and_frees_its_thread():
    """A filter stuck in a Python loop (catching ``Exception`` too) is stopped at the limit, and
    its thread ends soon after (it no longer takes a core); a fast one is untouched."""
    import threading
    import time

    def spins(data, cfg):
        while True:
            try:
                sum(range(1000))
            except Exception:
                pass

    from workbench.core.timeout import EstimatorTimedOut, call_with_timeout

    t0 = time.monotonic()
    with pytest.raises(EstimatorTimedOut, match="timed out after 0.5 s"):
        call_with_timeout(spins, (None, None), 0.5, "spins")
    assert time.monotonic() - t0 < 3
    alive = lambda: [t for t in threading.enumerate() if t.name == "workbench estimator spins"]  # noqa: E731
    deadline = time.monotonic() + 5
    while alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(), "the abandoned loop still runs"
    assert call_with_timeout(lambda data, cfg: 42, (None, None), 5.0, "quick") == 42
    assert call_with_timeout(lambda data, cfg: 42, (None, None), 0.0, "quick") == 42  # 0: called directly
    with pytest.raises(ZeroDivisionError):  # what an estimator raises comes through as it was
        call_with_timeout(lambda data, cfg: 1 / 0, (None, None), 5.0, "bad")


@pytest.mark.parametrize("given, limit", [("2.5", 2.5), ("0", 0.0), ("none", 0.0), ("OFF", 0.0), ("inf", 0.0)])
def test_the_timeout_setting(given, limit):
    from workbench.sweeps import grid

    exp = get("sea")
    assert grid.parse_value(exp, grid.resolve_key(exp, "estimator-timeout"), given) == limit
    assert workbench.configure("sea").estimator_timeout == 600.0  # the default
    assert workbench.configure("sea", estimator_timeout=0).estimator_timeout == 0.0


@pytest.mark.parametrize("bad", [-1.0, float("nan"), "soon"])
def test_a_bad_timeout_is_one_line(bad):
    with pytest.raises(WorkbenchError, match="--estimator-timeout"):
        workbench.configure("sea", estimator_timeout=bad)


def test_a_sweep_over_an_estimator_that_never_returns_ends(tmp_path, plugin):
    """A sweep whose cells each have an estimator asleep for ever: its worker processes pay the
    limit once per cell and go on (not poisoned), the sweep ends, the others' rows are there."""
    import pyarrow.parquet as pq

    r = wb("sweep", "sea", "--grid", "lam=0.9,0.99", "--set", "duration=20", "--set", "estimator-timeout=1",
           "--estimators", f"geometric,{plugin}:sleeps_forever", "--runs", "4", "--jobs", "2",
           "--out", str(tmp_path / "sw"), timeout=300)
    assert r.returncode == 0, r.stderr
    rows = pq.read_table(tmp_path / "sw" / "tasks").to_pandas()
    failed = rows[rows["failed"]]
    assert set(failed["estimator"]) == {"sleeps_forever"} and failed["unit"].str.contains("timed out").all()
    assert len(set(rows[(rows["estimator"] == "geometric") & ~rows["failed"]]["run"])) == 4


def test_psd_takes_sylvester_s_shortcut_only_where_it_is_sure():
    """estimator.psd: 2x2 and 3x3 covariances whose leading minors are positive pass without their
    eigenvalues; a singular PSD one (a zero minor) is asked the eigenvalues and passes; an indefinite
    one whose diagonal is positive, and one indefinite only to round-off's size, are told apart."""
    from workbench.core.estimator import EstimateError, _leading_minors_positive, psd

    good = np.array([[[2.0, 0.5, 0.1], [0.5, 1.0, 0.2], [0.1, 0.2, 0.5]]] * 3)
    singular = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    bad = np.array([[1.0, 0.0, 0.9], [0.0, 1.0, 0.9], [0.9, 0.9, 1.0]])   # eigenvalue 1 - 0.9 sqrt(2) < 0
    assert _leading_minors_positive(good).all()
    assert not _leading_minors_positive(np.stack([singular, bad])).any()
    assert not _leading_minors_positive(np.eye(4)[None]).any()            # larger: the eigenvalues decide
    psd(np.concatenate([good, singular[None]]), "cov")
    psd(np.array([[1.0, 1.0], [1.0, 1.0 - 1e-13]]), "cov")               # indefinite by round-off: PSD
    with pytest.raises(EstimateError, match="not positive semi-definite at row 1"):
        psd(np.stack([good[0], bad]), "cov")
    with pytest.raises(EstimateError, match="not positive semi-definite"):
        psd(np.array([[[1.0, 2.0], [2.0, 1.0]]]), "cov")
