"""The metric interface: a metric's figures against hand-computed ones (runs pooled or averaged,
the settling window, the chi-square band, an efficiency and its Monte Carlo error), and a
researcher's own metric through every path (a spec on the command line, a function through the
API, an installed entry point): in the table, the metrics JSON, the sweeps' rows and the
recording of every experiment it applies to, and a broken one named in one line.
"""

import json
import math
import textwrap

import numpy as np
import pyarrow.parquet as pq
import pytest
from launcher import cli

import workbench
from workbench.core.registry import get
from workbench.errors import WorkbenchError
from workbench.estimation.metrics import chi2_band
from workbench.metrics import statistics as figures
from workbench.metrics.base import Metric, Values
from workbench.recording import readback

T = np.arange(6.0)
RUNS = [{"a": {"err": Values([1, 1, 3, 3, 5, 5], T), "nees": Values([2, 2, 2, 4, 4, 4], T),
               "bound": Values([1, 1, 1, 1, 1, 1], T), "one": Values([2.0])}},
        {"a": {"err": Values([1, 1, 1, 1, 1, 1], T), "nees": Values([2, 2, 2, 2, 2, 2], T),
               "bound": Values([1, 1, 1, 1, 1, 1], T), "one": Values([4.0])}}]
METRICS = [Metric("err", None, "m", "an error"), Metric("err_mean", None, "m", "its runs' RMS, averaged",
                                                        across="mean"),
           Metric("nees", None, "", "a NEES", reduce="mean", dimension=2), Metric("bound", None, "m", "a bound"),
           Metric("one", None, "", "one value a run", reduce="mean", across="mean"),
           Metric("eff", None, "", "err over bound", efficiency=("err", "bound"))]


def test_figures_against_hand_computed_ones():
    runs = [{"a": {**r["a"], "err_mean": r["a"]["err"]}} for r in RUNS]
    f = figures.statistics(METRICS, runs, settle=2.0)["a"]
    # pooled: the RMS of every counted sample of both runs (steps t >= 2): 3,3,5,5 and 1,1,1,1
    assert f["err"] == pytest.approx(math.sqrt((9 + 9 + 25 + 25 + 4) / 8))
    assert f["err_whole_run"] == pytest.approx(math.sqrt((1 + 1 + 9 + 9 + 25 + 25 + 6) / 12))
    # across="mean": each run's RMS, their mean and (population) spread
    one, two = math.sqrt((9 + 9 + 25 + 25) / 4), 1.0
    assert f["err_mean"] == pytest.approx((one + two) / 2) and f["err_mean_std"] == pytest.approx(abs(one - two) / 2)
    assert f["one"] == 3.0 and f["one_std"] == 1.0 and "one_whole_run" not in f
    # a NEES: its mean, the band for two runs of 2 dof, the share of counted steps whose mean over runs is in it
    lo, hi = chi2_band(2, 2)
    assert f["nees"] == pytest.approx((2 + 4 + 4 + 4 + 2 + 2 + 2 + 2) / 8) and f["nees_band"] == [lo, hi]
    per_step = np.array([2.0, 3.0, 3.0, 3.0])
    assert f["nees_inside_band"] == pytest.approx(np.mean((per_step >= lo) & (per_step <= hi)))
    # an efficiency: RMS error over RMS bound; its Monte Carlo error from the runs' mean squares
    assert f["eff"] == pytest.approx(f["err"] / 1.0)
    sq = np.array([(9 + 9 + 25 + 25) / 4, 1.0])
    assert f["eff_se"] == pytest.approx(f["eff"] * 0.5 * sq.std(ddof=1) / (math.sqrt(2) * sq.mean()))
    rows = figures.run_rows(METRICS, runs[0], settle=2.0)["a"]
    assert rows["err"] == pytest.approx(one) and rows["eff"] == pytest.approx(one) and rows["one"] == 2.0


def test_renamed_keys_read_both_ways():
    stats = {"estimators": {"e": {"position_rmse": 1.5}}, "metric_table": {"anees": {"band": [1, 2]}}}
    renamed = {"rmse.position": "position_rmse", "/nees_band": "/metric_table.anees.band"}
    figures.add_renamed(stats, renamed)
    assert stats["estimators"]["e"]["rmse"]["position"] == 1.5 and stats["nees_band"] == [1, 2]
    old = {"estimators": {"e": {"rmse": {"position": 2.5}}}, "nees_band": [3, 4]}
    figures.upgrade(old, renamed)
    assert old["estimators"]["e"]["position_rmse"] == 2.5 and old["metric_table"]["anees"]["band"] == [3, 4]


def test_every_experiment_declares_its_metrics_in_one_shape():
    for name in ("omni", "sea", "terrain"):
        exp = get(name)
        metrics = exp.metrics()
        assert len({m.name for m in metrics}) == len(metrics) and all(m.source == "built-in" for m in metrics)
        assert set(exp.parts.table_columns) <= {m.name for m in metrics}
        for _, _, bound, eff in exp.parts.bounds:
            assert bound in {m.name for m in metrics} and eff in {m.name for m in metrics}
    with pytest.raises(WorkbenchError, match="a letter, then"):
        Metric("2bad", None, "", "")


PLUGIN = textwrap.dedent('''
    import numpy as np

    import workbench


    @workbench.metric(unit="m", description="the last step's position error")
    def final_error(data, est):
        if hasattr(data, "target"):                      # sea
            return workbench.Values([np.hypot(*(data.target[-1, :2] - est.position[-1]))])
        if hasattr(est, "pose"):                         # omni: the last grid step
            last = np.searchsorted(est.steps, data.grid[-1])
            return workbench.Values([np.hypot(*(data.truth[data.grid[-1], :2] - est.pose[last, :2]))])
        return None                                      # terrain: not a time series


    def broken(data, est):
        raise RuntimeError("deliberately broken")
''')


def test_a_metric_of_your_own_everywhere(tmp_path):
    """A spec on the command line: in the table, the JSON, the recording, a sweep's rows; the
    same number as the experiment's own figure where they measure the same thing."""
    (tmp_path / "mine.py").write_text(PLUGIN)
    spec = f"{tmp_path / 'mine.py'}:final_error"
    for experiment, args in (("sea", ("--duration", "10")), ("omni", ("--duration", "40"))):
        out, m = tmp_path / f"{experiment}.rrd", tmp_path / f"{experiment}.json"
        r = cli(experiment, "--runs", "2", *args, "--add-metrics", spec, "--out", str(out), "--metrics", str(m))
        assert r.returncode == 0, r.stderr
        assert "final_error m" in r.stdout.split("\n\n")[1], r.stdout     # a column of the table
        stats = json.loads(m.read_text())
        assert stats["metric_table"]["final_error"]["source"] == spec and stats["config"]["add_metrics"] == [spec]
        for name, e in stats["estimators"].items():
            assert e["final_error"] >= 0
            if experiment == "omni":   # the experiment's own last-step error, RMS over runs: the same here
                assert e["final_error"] == pytest.approx(e["final_position"], rel=1e-9), name
        counts = readback.row_counts(out)
        assert not any("/final_error/" in k for k in counts)   # not a time series: no curve
    r = cli("replay", str(tmp_path / "sea.rrd"))
    assert r.returncode == 0 and "reproduces" in r.stdout, r.stdout + r.stderr
    r = cli("sweep", "sea", "--grid", "lam=0.98,1", "--runs", "2", "--set", "duration=10", "--set",
            f"add_metrics={spec}", "--out", str(tmp_path / "sw"))
    assert r.returncode == 0, r.stderr
    rows = pq.read_table(tmp_path / "sw" / "tasks").to_pylist()
    assert len([x for x in rows if x["metric"] == "final_error"]) == 2 * 2 * 6   # cells x runs x estimators


def test_a_time_series_metric_from_python_is_drawn(tmp_path):
    def residual(data, est):
        """The azimuth error over its noise, at every step."""
        return Values((data.alpha - est.alpha) / data.sigma_alpha, data.t)

    res = workbench.run("sea", runs=3, duration=10.0, add_metrics=[residual], out=tmp_path / "a.rrd")
    e = res.metrics["estimators"]["geometric"]
    assert 0.7 < e["residual"] < 1.3          # the geometric fix passes the measured angle on: its noise
    assert res.config.add_metrics == ("local:residual",)
    counts = readback.row_counts(tmp_path / "a.rrd")
    assert counts["/metrics/residual/geometric"] == len(res.data.t)


def test_an_installed_metric_applies_to_every_experiment_it_names(tmp_path):
    """An entry point of the group workbench.metrics, as an installed package writes it."""
    site = tmp_path / "site"
    (site / "mymetrics").mkdir(parents=True)
    (site / "mymetrics" / "__init__.py").write_text(PLUGIN)
    dist = site / "mymetrics-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: mymetrics\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[workbench.metrics]\nsea.final_error = mymetrics:final_error\n")
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(site)}
    for experiment, args, has in (("sea", ("--duration", "10"), True), ("omni", ("--duration", "40"), False)):
        m = tmp_path / f"{experiment}.json"
        r = subprocess.run([sys.executable, "-m", "workbench", experiment, "--runs", "1", *args, "--out",
                            str(tmp_path / f"{experiment}.rrd"), "--metrics", str(m)], capture_output=True, text=True,
                           env=env, timeout=600)
        assert r.returncode == 0, r.stderr
        stats = json.loads(m.read_text())
        assert ("final_error" in stats["metric_table"]) == has, experiment       # named for sea alone
        if has:
            assert stats["metric_table"]["final_error"]["source"].startswith("entry point")


def test_a_broken_metric_costs_its_own_figures(tmp_path):
    (tmp_path / "mine.py").write_text(PLUGIN)
    m = tmp_path / "m.json"
    r = cli("sea", "--runs", "2", "--duration", "10", "--add-metrics", f"{tmp_path / 'mine.py'}:broken",
            "--out", str(tmp_path / "a.rrd"), "--metrics", str(m))
    assert r.returncode == 3 and "error: metric 'broken' failed on 'geometric': RuntimeError: deliberately" in r.stderr
    assert "Traceback" not in r.stderr
    stats = json.loads(m.read_text())
    assert stats["estimators"]["geometric"]["position_rmse"] > 0 and "broken" not in stats["estimators"]["geometric"]
    r = cli("sea", "--add-metrics", "nowhere:thing", "--out", str(tmp_path / "b.rrd"))
    assert r.returncode == 2 and "cannot import metric module 'nowhere'" in r.stderr and "Traceback" not in r.stderr
