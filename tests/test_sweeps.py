"""Sweeps: grids parsed through the contract, the same rows whichever executor runs the tasks
(a local pool or a real Dask ``LocalCluster`` on loopback), nothing lost or recomputed when a
sweep or a worker is killed, the report rebuilt from the Parquet files alone, bad input in one
line with exit code 2."""

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from launcher import cli, ctrl_c_as_a_terminal

from workbench.core.registry import get
from workbench.errors import WorkbenchError
from workbench.recording import readback
from workbench.sweeps import grid, runner

SEA = ("--set", "duration=5")


def _rows_of_a_run() -> int:
    """Rows a sea run of five seconds gives (bar the timings): every metric that applies to each
    default estimator (the Cramér-Rao bounds and efficiencies among them; the NEES and the
    innovations' figures only where there is a covariance or innovations), as the contract counts them."""
    sea = get("sea")
    cfg = sea.validate(sea.configure(duration=5.0))
    summary = sea.evaluate(sea.run_once(cfg, 0, sea.select()), cfg, 0)
    return sum(len([k for k in row if k != "seconds"]) for row in sea.run_metrics(summary, cfg).values())


ROWS = _rows_of_a_run()


def rows(folder: Path) -> dict:
    """Every row of a sweep folder, keyed by what identifies it (timings left out: they vary)."""
    t = pa.concat_tables([pq.read_table(f) for f in sorted((folder / "tasks").glob("*.parquet"))])
    out = {}
    for r in t.select(["cell", "run", "estimator", "metric", "value"]).to_pylist():
        key = (r["cell"], r["run"], r["estimator"], r["metric"])
        assert key not in out, f"row {key} twice"
        out[key] = r["value"]
    return {k: v for k, v in out.items() if k[3] != "seconds"}


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(a[k] == b[k] or (math.isnan(a[k]) and math.isnan(b[k])) for k in a)


def test_grid_keys_and_values_through_the_contract():
    sea = get("sea")
    g = grid.parse(sea, ["sigma-alpha=0.5,1", "window=60,120", "robust=off,on", "image-size=960x540", "order=3,5"])
    assert g == {"sigma_alpha_arcmin": (0.5, 1.0), "window": (60, 120), "robust": (False, True),
                 "image_size": ((960, 540),), "order": (3, 5)}
    cells = grid.cells(g)
    assert len(cells) == 16 and cells[0]["sigma_alpha_arcmin"] == 0.5 and cells[-1]["order"] == 5
    assert grid.expand(sea, {"order": 3}) == {"order_alpha": 3, "order_beta": 3}
    for bad, needle in (("nope=1,2", "no setting 'nope'"), ("lam=abc", "could not convert"), ("runs=1,2", "sets runs"),
                        ("lam=1,1", "repeats a value"), ("lam", "KEY=V1,V2"), ("scenario=moon", "choose from")):
        with pytest.raises(WorkbenchError, match=needle):
            grid.parse(sea, [bad])


def test_local_pool_and_dask_give_the_same_rows(tmp_path):
    """The same seeds, the same rows, whichever executor: a process pool and a LocalCluster of two
    workers on loopback; the run k of every cell draws the same noise (common random numbers)."""
    pytest.importorskip("distributed")
    spec = {"lam": (0.95, 1.0), "window": (60, 120)}
    a = runner.sweep("sea", None, spec, {"duration": 5.0}, runs=3, out=tmp_path / "pool", jobs=2, report=False)
    b = runner.sweep("sea", None, spec, {"duration": 5.0}, runs=3, out=tmp_path / "dask", local_cluster=2,
                     report=False)
    assert a.tasks == b.tasks == a.computed == b.computed and "Dask" in b.executor
    ra, rb = rows(tmp_path / "pool"), rows(tmp_path / "dask")
    assert len(ra) == 4 * 3 * ROWS and same(ra, rb)   # cells x runs x rows
    # geometric does not depend on lam or window: with the same draws, every cell gives it the same
    assert ra[(0, 2, "geometric", "position_rmse")] == ra[(3, 2, "geometric", "position_rmse")]
    assert ra[(0, 2, "rls", "position_rmse")] != ra[(2, 2, "rls", "position_rmse")]  # lam acts on rls


def _args(out: Path, *extra: str) -> list[str]:
    return ["sweep", "sea", "--grid", "lam=0.98,1", "--runs", "10", "--chunk", "1", *SEA, "--out", str(out), *extra]


def _wait_for(folder: Path, n: int, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    t0 = time.time()
    while len(list((folder / "tasks").glob("*.parquet"))) < n:
        assert proc.poll() is None, "the sweep ended before it could be stopped"
        assert time.time() - t0 < timeout
        time.sleep(0.05)


@pytest.mark.parametrize("how", ["killed", "interrupted"])
def test_a_stopped_sweep_resumes_without_recomputing(tmp_path, how):
    """SIGKILL to the whole sweep (pool included), or Ctrl-C (SIGINT, exit 130 and a line saying
    how to finish): the finished tasks stay, untouched by the resumed sweep, which computes only
    the others; every row is there once. (The stopped sweep is a process of its own, which the
    signal ends; the resume, a plain command, runs in this one.)"""
    out = tmp_path / "sw"
    proc = subprocess.Popen([sys.executable, "-m", "workbench", *_args(out)], start_new_session=True,
                            stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_as_a_terminal)
    _wait_for(out, 6, proc)
    os.killpg(proc.pid, signal.SIGKILL if how == "killed" else signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    if how == "interrupted":
        assert proc.returncode == 130 and "--resume" in err and "interrupted" in err, err
    before = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in (out / "tasks").glob("*.parquet")}
    assert 6 <= len(before) < 20
    r = cli(*_args(out, "--resume"))
    assert r.returncode == 0, r.stderr
    done = f"20 task(s) on local pool, 2 process(es): {len(before)} done before, {20 - len(before)} computed"
    assert done in r.stdout
    after = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in (out / "tasks").glob("*.parquet")}
    assert len(after) == 20 and all(after[k] == v for k, v in before.items())
    assert len(rows(out)) == 2 * 10 * ROWS and not list((out / "tasks").glob(".*.tmp"))


def test_a_killed_worker_loses_nothing(tmp_path):
    """A Dask worker killed mid-sweep: the scheduler reschedules its task, every row arrives once."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        out = tmp_path / "sw"
        done = {}

        def go():
            done["result"] = runner.sweep("sea", None, {"lam": (0.98, 1.0)}, {"duration": 5.0}, runs=8, chunk=1,
                                          out=out, scheduler=cluster.scheduler_address, report=False)

        thread = threading.Thread(target=go)
        thread.start()
        t0 = time.time()
        while len(list((out / "tasks").glob("*.parquet"))) < 4 and time.time() - t0 < 120:
            time.sleep(0.02)
        pids = client.run(os.getpid)
        os.kill(next(iter(pids.values())), signal.SIGKILL)
        assert len(list((out / "tasks").glob("*.parquet"))) < 16, "the sweep ended before the kill"
        thread.join(timeout=300)
        assert not thread.is_alive() and done["result"].computed == 16
    assert len(rows(out)) == 2 * 8 * ROWS


def test_the_report_rebuilds_from_the_parquet_files_alone(tmp_path):
    out = tmp_path / "sw"
    r = cli("sweep", "sea", "--grid", "window=60,120", "--grid", "order=3,5", "--runs", "3", *SEA, "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert "### position_rmse (m)" in r.stdout and "12 task(s) on local pool" in r.stdout
    summary = (out / "summary.csv").read_text().splitlines()
    assert summary[0].startswith("cell,window,order,estimator,metric,unit,n,mean,std,ci95_lo,ci95_hi")
    assert len(summary) == 1 + 4 * (ROWS + 6)       # every figure and the timings, per cell
    assert {p.name for p in out.glob("*.png")} == {f"{m}_vs_{k}.png" for m in ("position_rmse", "rmse_alpha", "anees")
                                                    for k in ("window", "order")}
    counts = readback.row_counts(out / "sweep.rrd")
    assert counts["/sweep/window/position_rmse/window-rls"] == 2 and counts["/sweep/order/anees/ekf"] == 2
    colleague = tmp_path / "sent"
    shutil.copytree(out / "tasks", colleague / "tasks")      # the Parquet files, nothing else
    r = cli("sweep-report", str(colleague))
    assert r.returncode == 0, r.stderr
    assert (colleague / "summary.csv").read_text() == (out / "summary.csv").read_text()
    assert (colleague / "summary.md").read_text() == (out / "summary.md").read_text()
    meta = pq.read_table(next((out / "tasks").glob("*.parquet"))).to_pylist()[0]
    assert meta["version"] and len(meta["config_hash"]) == 16 and meta["seed"] == 0 and meta["scenario"] == "paper"
    assert json.loads((out / "sweep.json").read_text())["grid"] == {"window": [60, 120], "order": [3, 5]}


def test_a_plugin_estimator_in_a_sweep(tmp_path):
    plugin = tmp_path / "mine.py"
    plugin.write_text("from workbench.experiments.sea.estimate import Estimate\n\n"
                      "def offset(data, cfg):\n    return Estimate(position=data.target[:, :2] + [3.0, -4.0])\n")
    out = tmp_path / "sw"
    r = cli("sweep", "sea", "--grid", "sigma-alpha=0.5,1", "--runs", "2", *SEA, "--estimators",
            f"ekf,{plugin}:offset", "--out", str(out))
    assert r.returncode == 0, r.stderr
    got = rows(out)
    assert all(got[(c, k, "offset", "position_rmse")] == pytest.approx(5.0, rel=1e-12) for c in (0, 1) for k in (0, 1))


def test_presets(tmp_path):
    r = cli("sweep", "terrain", "--list-presets")
    assert r.returncode == 0 and "paper-grid" in r.stdout and "size (3) x max_linear (3)" in r.stdout
    r = cli("sweep", "sea", "--preset", "ar-models", "--runs", "1", "--set", "duration=5", "--out", str(tmp_path / "p"))
    assert r.returncode == 0, r.stderr
    assert "27 task(s)" in r.stdout and "| lam | window | order | geometric | rls | window-rls | ekf |" in r.stdout


@pytest.mark.parametrize("args, needle", [
    (("--grid", "nope=1,2"), "sea has no setting 'nope'"),
    (("--grid", "lam=2"), "--lam must be in (0, 1]"),
    (("--grid", "window=abc"), "invalid literal"),
    ((), "nothing to sweep"),
    (("--grid", "lam=1", "--preset", "nope"), "no preset 'nope'"),
    (("--grid", "lam=1", "--scheduler", "tcp://127.0.0.1:1"), "cannot reach the Dask scheduler"),
    (("--grid", "lam=1", "--estimators", "magic"), "unknown estimator 'magic'"),
    (("--grid", "lam=1", "--set", "lam"), "KEY=VALUE"),
    (("--grid", "lam=1", "--chunk", "0"), "--chunk must be at least 1"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, needle):
    out = tmp_path / "sw"
    r = cli("sweep", "sea", "--runs", "1", "--out", str(out), *args)
    assert r.returncode == 2 and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (out / "tasks").exists() or not list((out / "tasks").iterdir())


def test_an_existing_folder_needs_force_or_resume(tmp_path):
    out = tmp_path / "sw"
    args = ("sweep", "sea", "--grid", "lam=1", "--runs", "1", *SEA, "--out", str(out))
    assert cli(*args).returncode == 0
    r = cli(*args)
    assert r.returncode == 2 and "--resume" in r.stderr and "--force" in r.stderr
    r = cli("sweep", "sea", "--grid", "lam=0.9", "--runs", "1", *SEA, "--out", str(out), "--resume")
    assert r.returncode == 2 and "its grid differ" in r.stderr
    r = cli(*args, "--force")
    assert r.returncode == 0 and "0 done before, 1 computed" in r.stdout
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    r = cli("sweep", "sea", "--grid", "lam=1", "--runs", "1", "--out", str(tmp_path / "other"), "--force")
    assert r.returncode == 2 and "holds no sweep" in r.stderr and (tmp_path / "other" / "notes.txt").exists()
