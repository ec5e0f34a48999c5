"""Long logs cost what their length does (issue 36): iSAM2 and the batch on a synthetic drive
twice as long (3,000 and 6,000 poses, trees and field grown to keep their density) take about
twice the time, under 3x (this process's CPU time, best of five), and iSAM2 takes no whole-graph
LM pass but at a run-away. Measured: 2.1x; with an LM pass every 20 s, as before issue 36, 3.6x
here and 4.4x from 7,000 to 14,000 poses. The limit is not the issue's 2.5x: iSAM2's own updates
grow a little faster than the log where the drive comes back to trees it saw long before (the
plain GTSAM loop's too, 3.2x from 7,000 to 14,000: ``benchmarks/bench_isam2.py --scaling``), and
under the suite's other worker this drive measured up to 2.6x."""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
import pytest
from launcher import DATA

from workbench import api
from workbench.experiments.omni import faults
from workbench.experiments.omni.algorithms import graph


def _drive(tmp_path, scale: float):
    f = faults.Faults(poses=int(3000 * scale), landmarks=int(70 * scale), area=150.0 * math.sqrt(scale),
                      max_range=17.0, seed=2)
    folder = faults.write(tmp_path / f"x{scale:g}", f)[0].parent
    cfg = api.configure("omni", "log", data=str(folder))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = api.get("omni").dataset(cfg, 0)
    return data, cfg


def _mrclam(robot: int):
    cfg = api.configure("omni", "mrclam", data=str(DATA / "mrclam6"), robot=robot)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = api.get("omni").dataset(cfg, 0)
    return data, cfg, graph.keyframes(data, cfg)


def _smoothers(data, cfg):
    kf = graph.keyframes(data, cfg)
    est = graph.isam2(data, cfg, kf)
    batch = graph.batch(data, cfg, kf, [graph.start_from("isam2", est, data, kf)])
    return est, batch


def test_a_log_twice_as_long_costs_about_twice_as_much(tmp_path):
    one, two = _drive(tmp_path, 1.0), _drive(tmp_path, 2.0)
    seconds = {1: [], 2: []}
    for _ in range(5):  # interleaved, best of five: a shared machine's load comes and goes (and xdist's other worker)
        for n, (data, cfg) in ((1, one), (2, two)):
            t0 = time.process_time()  # this process's CPU time: what other processes take is not counted
            est, batch = _smoothers(data, cfg)
            seconds[n].append(time.process_time() - t0)
            for e in (est, batch):  # and right: the whole run within a metre of the truth
                d = (e.smoothed if e.smoothed is not None else e.pose)[:, :2] - data.truth[e.steps, :2]
                rms = float(np.sqrt(np.mean(np.sum(d**2, axis=1))))
                assert rms < 1.0, (n, e.name, rms)
            assert est.lm_passes <= 2, est.lm_passes  # only at a run-away, not every 20 s
    ratio = min(seconds[2]) / min(seconds[1])
    assert ratio < 3.0, (seconds, ratio)


def test_isam2_following_itself_takes_a_landmark_named_twice_at_one_keyframe(tmp_path):
    """With 10 % of the bearings given another tree's id, a keyframe can hold two bearings of one
    landmark, the first making it enter: the gate then tests the second against the landmark
    before iSAM2 holds it (it raised from the Bayes tree before this was handled). A misread is
    left out far more often than a good bearing (measured: 46 % against 5.6 %; the batch re-gates
    them against its whole answer), and the whole run stays within 2 m of the truth (1.1 m)."""
    f = faults.Faults(poses=3000, misread=0.10, seed=0)
    folder = faults.write(tmp_path / "misread", f)[0].parent
    cfg = api.configure("omni", "log", data=str(folder))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = api.get("omni").dataset(cfg, 0)
    est = graph.isam2(data, cfg)
    wrong = faults.simulate(f)
    misread = np.flatnonzero(wrong["ids"] != wrong["true_ids"])
    out = np.isin(np.arange(len(wrong["ids"])), est.gated_bearings)
    good = np.ones(len(out), bool)
    good[misread] = False
    d = est.smoothed[:, :2] - data.truth[est.steps, :2]
    rms = float(np.sqrt(np.mean(np.sum(d**2, axis=1))))
    assert out[misread].mean() > 5 * out[good].mean() and rms < 2.0, (out[misread].mean(), out[good].mean(), rms)


@pytest.mark.skipif(not (DATA / "mrclam6").is_dir(), reason="the real MRCLAM data are not here")
def test_isam2_s_passes_at_run_aways_cost_at_most_a_budget_of_whole_solves(monkeypatch):
    """An iSAM2 that runs away again as soon as each pass rebuilds it (MRCLAM 6 robot 1 told a
    bearing sigma of 0.58 deg once did: 205 passes, 11 s against 1 s; since landmarks whose ids show
    misreads enter only where their rays check each other it no longer does, 0.42 m). Made here by
    calling every update with a correction over 1 mm or 0.01 deg a run-away: the passes' keyframes,
    summed, stay within PASS_BUDGET graphs of the log's length so far; iSAM2 is given up and says
    so (a failure), and the batch, which tries its other starts when iSAM2's answer fails its test,
    lands where it lands at the scenario's noise."""
    from workbench.experiments.omni.algorithms.graph import incremental

    data, cfg, kf = _mrclam(1)
    seconds: dict[str, list[float]] = {"plain": [], "run-away": []}
    for _ in range(2):  # interleaved, best of two, this process's CPU time: the machine's load is not counted
        for name, jump in (("plain", (incremental.JUMP_POSITION, incremental.JUMP_HEADING)),
                           ("run-away", (1e-3, math.radians(0.01)))):
            with monkeypatch.context() as m:
                m.setattr(incremental, "JUMP_POSITION", jump[0])
                m.setattr(incremental, "JUMP_HEADING", jump[1])
                t0 = time.process_time()
                graph.isam2(data, cfg, kf)
                seconds[name].append(time.process_time() - t0)
    # an iSAM2 that runs away at every update costs at most a small multiple of one that does not
    # (0.5-0.7x here, as it gives up, each pair alike under a load of 14 on 2 cores; 11x before the budget): a
    # ratio in one process, not seconds, which a loaded CI machine stretches (4.06 s against a bound of 4 there)
    ratio = min(seconds["run-away"]) / min(seconds["plain"])
    assert ratio < 3.0, (seconds, ratio)
    monkeypatch.setattr(incremental, "JUMP_POSITION", 1e-3)
    monkeypatch.setattr(incremental, "JUMP_HEADING", math.radians(0.01))
    inc = incremental._Incremental(data, cfg, kf)
    for e in range(len(kf.steps)):
        inc.step(e)
        assert inc.pass_work <= incremental.PASS_BUDGET * (e + 1)
    assert inc.gave_up is not None and inc.isam is None and inc.failures >= 1 and inc.passes > 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = api.run("omni", "mrclam", data=str(DATA / "mrclam6"), robot=1, estimators=["isam2", "gtsam-batch"])
    got = run.metrics["estimators"]
    assert got["isam2"]["failures"] >= 1
    # the diagnosis names the give-up first (its time, the keyframe's), and never calls it consistent
    d = got["isam2"]["diagnosis"]
    at = data.t[kf.steps[inc.gave_up]] - data.t[0]
    assert d["remarks"] == [r for r in d["remarks"] if r.startswith(f"iSAM2 gave up at {at:.0f} s")] != []
    assert d["reason"].startswith("iSAM2 gave up") and d["consistent"] is False
    from workbench.metrics import diagnosis
    assert diagnosis.line(d).startswith(f"iSAM2 gave up at {at:.0f} s, "), diagnosis.line(d)
    assert got["gtsam-batch"]["position_rmse"] < 0.3   # 0.138 m; 0.144 at the scenario's noise


@pytest.mark.skipif(not (DATA / "mrclam6").is_dir(), reason="the real MRCLAM data are not here")
def test_a_jump_that_a_second_step_settles_gets_no_whole_graph_pass(monkeypatch):
    """A landmark seen again after a blind stretch turns iSAM2's heading back by 10-30 deg: a jump
    past the run-away thresholds that one more Gauss-Newton iteration leaves where it is. MRCLAM 6
    robot 3 has three such jumps and one run-away; with the check it takes one LM pass where it took
    five, and its trajectory ends within 2 cm of the one with every pass (1.4 cm: each pass re-gates
    the bearings at its answer, :class:`.pruned._Pruned`, so more passes leave a few more out; 1 cm
    before they did)."""
    from workbench.experiments.omni.algorithms.graph import incremental

    data, cfg, kf = _mrclam(3)
    checked = graph.isam2(data, cfg, kf)
    monkeypatch.setattr(incremental._Incremental, "_settles", lambda self: False)
    every = graph.isam2(data, cfg, kf)
    assert checked.lm_passes < every.lm_passes
    d = np.linalg.norm(checked.smoothed[:, :2] - every.smoothed[:, :2], axis=1)
    assert d.max() < 0.02, d.max()
