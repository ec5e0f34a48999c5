"""``workbench tune``: a study proposes by Optuna, runs its trials as the sweeps' tasks, keeps every
trial's rows, and resumes after a kill asking and running exactly what an uninterrupted study does;
the pool and a Dask LocalCluster give the same trials; bad input is one line, nothing touched."""

import json
import os
import signal
import subprocess
import sys
import time
import tomllib

import numpy as np
import pyarrow.parquet as pq
import pytest
from launcher import cli

from workbench.tuning import files as studies

SMALL = ("--set", "duration=10", "--set", "assume-sigma-acc=1.0", "--runs", "2", "--estimator", "ekf")


def trials_of(folder) -> list[tuple]:
    """Every trial of a study folder: (number, state, params, value), in number order."""
    _, study, _ = studies.load(folder)
    return [(t.number, t.state.name, dict(t.params), t.value) for t in sorted(study.trials, key=lambda t: t.number)]


def test_a_study_writes_its_report_and_best_toml_runs(tmp_path):
    out = tmp_path / "study"
    r = cli("tune", "sea", "--param", "sigma-acc=0.01:1:log", "--trials", "6", "--batch", "3", "--jobs", "1",
            "--out", str(out), *SMALL)
    assert r.returncode == 0, r.stderr
    assert "tuned as what the estimators assume (assume_sigma_acc)" in r.stderr
    got = trials_of(out)
    assert [t[0] for t in got] == list(range(6)) and all(t[1] == "COMPLETE" for t in got)
    assert got[0][2] == {"assume_sigma_acc": 1.0}              # the config's own value is the start
    rows = pq.read_table(out / "trials").to_pandas()
    assert set(rows.trial) == set(range(6)) and set(rows.run) == {0, 1} and "p.assume_sigma_acc" in rows
    # every trial's objective is the mean over its runs of the EKF's NLL in its rows
    for n, _, params, value in got:
        nll = rows[(rows.trial == n) & (rows.estimator == "ekf") & (rows.metric == "nll")]
        assert value == pytest.approx(nll.value.mean(), rel=1e-12)
        assert nll["p.assume_sigma_acc"].iloc[0] == params["assume_sigma_acc"]
    best = min(got, key=lambda t: t[3])
    toml = tomllib.loads((out / "best.toml").read_text())
    assert toml["assume_sigma_acc"] == best[2]["assume_sigma_acc"] and toml["duration"] == 10.0
    assert f"**Best: trial {best[0]}" in (out / "summary.md").read_text()
    assert {"objective.png", "param-assume_sigma_acc.png", "study.rrd"} <= {p.name for p in out.iterdir()}
    from workbench.recording import readback  # the study's recording reads back: the objective on a trial timeline

    t, v = readback.series(out / "study.rrd", "/objective/trial", timeline="trial")
    assert np.allclose(t * 1e9, [g[0] for g in got]) and np.allclose(v, [g[3] for g in got])  # (a sequence, read as ns)
    again = cli("sea", "--config", str(out / "best.toml"), "--estimators", "ekf", "--runs", "2",
                "--out", str(tmp_path / "best.rrd"), "--metrics", str(tmp_path / "best.json"))
    assert again.returncode == 0, again.stderr
    m = json.loads((tmp_path / "best.json").read_text())
    assert m["config"]["assume_sigma_acc"] == best[2]["assume_sigma_acc"]
    assert m["estimators"]["ekf"]["nll"] == pytest.approx(best[3], rel=1e-9)   # the same runs, the same figure


def test_a_killed_study_resumes_to_the_same_trials(tmp_path):
    args = ("tune", "sea", "--param", "sigma-acc=0.01:1:log", "--param", "sigma-alpha=0.3:3:log", "--trials", "8",
            "--batch", "4", "--jobs", "1", *SMALL)
    whole = tmp_path / "whole"
    assert cli(*args, "--out", str(whole)).returncode == 0
    killed = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "workbench", *args, "--out", str(killed)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and len(list((killed / "trials").glob("*.parquet"))) < 5:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)   # mid-batch: the second batch asked, one of its trials done
    proc.wait()
    before = trials_of(killed)
    assert any(t[1] == "RUNNING" for t in before) and len(before) < 8 + 1
    r = cli(*args, "--out", str(killed), "--resume")
    assert r.returncode == 0, r.stderr
    a, b = trials_of(whole), trials_of(killed)
    assert [t[0] for t in b] == list(range(8))                  # every trial once, none lost
    assert a == b                                               # the same proposals, the same values
    assert len(list((killed / "trials").glob("*.parquet"))) == 8


def test_the_pool_and_a_local_cluster_give_the_same_trials(tmp_path):
    args = ("tune", "sea", "--param", "sigma-acc=0.01:1:log", "--trials", "4", "--batch", "2", *SMALL)
    assert cli(*args, "--jobs", "2", "--out", str(tmp_path / "pool")).returncode == 0
    r = cli(*args, "--local-cluster", "2", "--out", str(tmp_path / "dask"))
    assert r.returncode == 0, r.stderr
    assert "local Dask cluster (2 workers)" in r.stdout
    assert trials_of(tmp_path / "pool") == trials_of(tmp_path / "dask")


@pytest.mark.parametrize("args,said", [
    (("--param", "sigma-acc=1:0.1"), "--param sigma-acc: LOW must be below HIGH, got 1:0.1"),
    (("--param", "sigma-acc=0:1:log"), "--param sigma-acc: a log scale needs positive bounds"),
    (("--param", "regressors=0:1"), "--param regressors: regressors is not a number setting"),
    (("--param", "nothing=0:1"), "--param nothing: sea has no number setting 'nothing'"),
    (("--param", "sigma-acc=a:1"), "--param sigma-acc: LOW and HIGH must be numbers"),
    (("--param", "sigma-acc=0.1:1:lin"), "the third part is 'log' or nothing"),
    (("--param", "sigma-acc"), "must look like NAME=LOW:HIGH"),
    (("--param", "window=1.5:10"), "--param window: window is a whole number"),
    (("--param", "lam=0.5:2"), "--lam must be in (0, 1]"),
    (("--param", "sigma-acc=0.01:1", "--objective", "nothing"), "--objective 'nothing': likelihood, nees, rmse"),
    ((), "nothing to tune"),
])
def test_bad_input_is_one_line_and_touches_nothing(tmp_path, args, said):
    out = tmp_path / "study"
    r = cli("tune", "sea", *args, "--trials", "2", "--out", str(out))
    assert r.returncode == 2 and said in r.stderr, r.stderr
    assert "\n" not in r.stderr.strip() and "Traceback" not in r.stderr
    assert not out.exists()


def test_a_resume_with_another_space_or_an_objective_needing_truth_touches_nothing(tmp_path):
    out = tmp_path / "study"
    assert cli("tune", "sea", "--param", "sigma-acc=0.01:1:log", "--trials", "2", "--batch", "2", "--jobs", "1",
               "--out", str(out), *SMALL).returncode == 0
    listing = {p: p.stat().st_mtime_ns for p in out.rglob("*")}
    r = cli("tune", "sea", "--param", "sigma-acc=0.01:2:log", "--trials", "2", "--batch", "2", "--jobs", "1",
           "--out", str(out), "--resume", *SMALL)
    assert r.returncode == 2 and "holds another study (its space differ)" in r.stderr, r.stderr
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*")} == listing
    # a log without truth: the NEES needs the truth
    log = tmp_path / "log"
    assert cli("sea", "--duration", "10", "--export-data", str(log), "--out", str(tmp_path / "x.rrd")).returncode == 0
    (log / "truth.csv").unlink()
    r = cli("tune", "sea", "--scenario", "log", "--set", f"data={log}", "--param", "sigma-acc=0.01:1:log",
           "--objective", "nees", "--trials", "2", "--out", str(tmp_path / "t2"))
    assert r.returncode == 2 and "--objective nees needs the truth" in r.stderr, r.stderr
    assert not (tmp_path / "t2").exists()
    r = cli("tune", "sea", "--scenario", "log", "--set", f"data={log}", "--param", "sigma-acc=0.01:1:log",
            "--trials", "2", "--batch", "2", "--jobs", "1", "--runs", "1", "--out", str(tmp_path / "t3"))
    assert r.returncode == 0, r.stderr                         # by likelihood it needs none
    assert np.isfinite([t[3] for t in trials_of(tmp_path / "t3")]).all()
