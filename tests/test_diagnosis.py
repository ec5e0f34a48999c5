"""The truth-free diagnosis (:mod:`workbench.metrics.diagnosis`): the noise fit against draws
of known scale, tail and censoring; the redundancy against the hat matrix of a small graph; the
verdicts on hand-made evidence; and the end-to-end on synthetic logs with a known fault."""

import json
import math

import gtsam
import numpy as np
import pytest
from launcher import cli

from workbench.estimation import noisefit
from workbench.estimation.consistency import Innovations
from workbench.estimation.redundancy import hat_traces
from workbench.experiments.omni import faults
from workbench.metrics import diagnosis

GATE = 6.634896601021214  # chi-square, 1 dof, 99 %


def test_the_scale_is_found_under_a_gate_that_hid_what_it_dropped():
    """q = 4 chi2_1 with the 99 % gate's drops censored (no figure): the kept ones alone average
    1.7 (the truncated distribution); the censored likelihood finds 4 within its interval."""
    rng = np.random.default_rng(1)
    q = 4.0 * rng.chisquare(1, 4000)
    seen = np.where(q > GATE, np.nan, q)
    assert np.nanmean(seen) < 2.0
    fit = noisefit.fit(seen, 1, censored_at=GATE, tail=False)
    lo, hi = fit.intervals["k"]
    assert lo < 4.0 < hi and abs(fit.k - 4.0) < 0.3


def test_a_tail_of_outliers_is_told_from_a_wider_noise():
    """5 % of bearings uniform on the circle (1 deg noise): the tail holds 5 % (+-1.5) and the core
    is the noise (k within 10 % of 1); a plain Gaussian 4x too narrow has no tail."""
    rng = np.random.default_rng(2)
    q = rng.chisquare(1, 4000)
    out = rng.random(4000) < 0.05
    q[out] = rng.uniform(-np.pi, np.pi, out.sum()) ** 2 / math.radians(1.0) ** 2
    plain, heavy, p = noisefit.tail_test(q, 1)
    assert p < 1e-6 and abs(heavy.eps - 0.05) < 0.015 and abs(heavy.k - 1.0) < 0.1
    assert plain.k > 20  # a Gaussian alone inflates the noise to take the outliers in
    _, heavy, p = noisefit.tail_test(4.0 * rng.chisquare(1, 4000), 1)
    assert p > 1e-3 or heavy.eps < 0.01


def test_the_state_and_the_measurement_noise_are_told_apart():
    """Innovations whose state part is 9x what the filter said and whose measurement part is
    right: a = 9, b = 1 within their intervals."""
    rng = np.random.default_rng(3)
    share = rng.uniform(0.05, 0.95, 5000)
    q = rng.chisquare(1, 5000) * (9.0 * share + (1.0 - share))
    fit = noisefit.fit(q, 1, share=share, tail=False)
    assert fit.intervals["a"][0] < 9.0 < fit.intervals["a"][1]
    assert fit.intervals["b"][0] < 1.0 < fit.intervals["b"][1]


def test_variance_components_of_a_consistent_group_hold_one():
    rng = np.random.default_rng(4)
    f, (lo, hi) = noisefit.variance_components(rng.chisquare(700, 1), 700.0)
    assert lo < 1.0 < hi and abs(f - 1.0) < 0.2


def test_the_groups_redundancies_against_the_hat_matrix():
    """A chain of poses with bearings to three points: each group's hat trace from the sparse
    solves equals the dense hat matrix's (the odometry's by what the others leave), and the traces
    add up to the unknowns."""
    g, v = gtsam.NonlinearFactorGraph(), gtsam.Values()
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([0.05, 0.02, 0.01]))
    g.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(), noise))
    groups = ["prior"]
    for k in range(1, 200):
        g.add(gtsam.BetweenFactorPose2(k - 1, k, gtsam.Pose2(0.5, 0.0, 0.01), noise))
        groups.append("odometry")
    pts = [gtsam.symbol("l", j) for j in range(3)]
    bn = gtsam.noiseModel.Isotropic.Sigma(1, 0.02)
    for k in range(200):
        v.insert(k, gtsam.Pose2(0.5 * k, 0.0, 0.01 * k))
        for j, key in enumerate(pts):
            if k % 2 == j % 2:
                g.add(gtsam.BearingFactor2D(k, key, gtsam.Rot2(0.3), bn))
                groups.append("bearing")
    for j, key in enumerate(pts):
        v.insert(key, gtsam.Point2(30.0 * j, 8.0))
    traces = hat_traces(g, v, groups, probes=400)
    A, _ = g.linearize(v).jacobian()
    H = A @ np.linalg.solve(A.T @ A, A.T)
    rows = np.repeat(groups, [g.at(k).dim() for k in range(g.size())])
    for name in ("prior", "bearing", "odometry"):
        exact = float(np.trace(H[np.ix_(rows == name, rows == name)]))
        assert traces[name] == pytest.approx(exact, abs=max(0.02 * exact, 1.0)), name
    assert sum(traces.values()) == pytest.approx(A.shape[1], abs=1e-6)


def _filter(q_kept, gated, n_censored=0, share=None):
    """A filter's innovations: kept ones of NIS ``q_kept``, gated ones with their NIS, and
    ``n_censored`` left out with none, at a 99 % gate."""
    q = np.concatenate([q_kept, gated, np.full(n_censored, np.nan)])
    kept = np.concatenate([np.ones(len(q_kept), bool), np.zeros(len(gated) + n_censored, bool)])
    r = None if share is None else 1.0 - share
    return Innovations.scalar(np.arange(len(q), dtype=float), np.sqrt(q), np.ones(len(q)), kept, r, 0.99)


def test_a_filter_that_gated_most_of_its_data_is_not_called_consistent():
    """The car log's failure: 87 % left out at a 99 % gate, the kept 13 % with a NIS near 1. The
    kept ones alone pass the NIS band; the diagnosis says the noise is too narrow, by about the
    factor drawn (3)."""
    rng = np.random.default_rng(5)
    q = 9.0 * rng.chisquare(1, 3000)
    kept = q <= GATE
    q = np.where(kept, q, np.nan)
    innov = _filter(q[kept], [], int((~kept).sum()))
    assert 0.5 < np.nanmean(innov.nis()) < 2.5 and (~innov.used).mean() > 0.3
    d = diagnosis.diagnose(diagnosis.from_innovations(innov))
    assert d["verdict"] == "too narrow" and 2.5 < d["factor"] < 3.6, d["reason"]
    assert d["left_out"] > 0.3 and d["left_out_expected"] == pytest.approx(0.01)


@pytest.mark.parametrize("case, verdict", [("right", "consistent"), ("wide", "too wide"), ("narrow", "too narrow"),
                                           ("outliers", "outliers"), ("few", "not enough data")])
def test_each_verdict_on_evidence_drawn_for_it(case, verdict):
    rng = np.random.default_rng(6)
    n = 20 if case == "few" else 3000
    scale = {"wide": 0.3**2, "narrow": 3.0**2}.get(case, 1.0)
    q = scale * rng.chisquare(1, n)
    if case == "outliers":
        out = rng.random(n) < 0.05
        q[out] = rng.uniform(-np.pi, np.pi, out.sum()) ** 2 / math.radians(1.0) ** 2
    kept = q <= GATE
    d = diagnosis.diagnose(diagnosis.from_innovations(_filter(q[kept], q[~kept])))
    assert d["verdict"] == verdict, d["reason"]
    if verdict in ("too wide", "too narrow"):
        assert d["factor"] == pytest.approx(math.sqrt(scale), rel=0.1)
    if verdict == "outliers":
        assert d["tail_share"] == pytest.approx(0.05, abs=0.015)


def test_the_odometry_is_named_where_the_state_share_tells():
    rng = np.random.default_rng(7)
    share = rng.uniform(0.05, 0.95, 4000)
    q = rng.chisquare(1, 4000) * (16.0 * share + (1.0 - share))
    kept = q <= GATE
    innov = _filter(q[kept], q[~kept], share=np.concatenate([share[kept], share[~kept]]))
    d = diagnosis.diagnose(diagnosis.from_innovations(innov), {"state": "odometry", "measurement": "bearings"})
    assert d["verdict"] == "too narrow" and d["group"] == "odometry", d["reason"]
    assert d["factor"] == pytest.approx(4.0, rel=0.15)
    assert diagnosis.line(d).startswith("too narrow x4")


def _diagnoses(folder, tmp_path, name):
    out = tmp_path / f"{name}.json"
    r = cli("omni", "--scenario", "log", "--data", str(folder), "--estimators", "ekf,gtsam-batch",
            "--out", str(tmp_path / f"{name}.rrd"), "--metrics", str(out))
    assert r.returncode == 0, r.stderr
    return {n: e["diagnosis"] for n, e in json.loads(out.read_text())["estimators"].items() if "diagnosis" in e}


def test_a_log_whose_odometry_covariance_is_ten_times_too_small(tmp_path):
    """3,000 poses of increments odometry, 150 trees, the stated odometry sigmas 10x too small:
    the EKF and the batch are "too narrow" on the odometry, by a factor of at least 5; with the
    true covariances both are "consistent"."""
    faults.write(tmp_path / "narrow", faults.Faults(odometry_stated=0.1))
    faults.write(tmp_path / "right", faults.Faults())
    narrow = _diagnoses(tmp_path / "narrow", tmp_path, "narrow")
    for name in ("ekf", "gtsam-batch"):
        assert narrow[name]["verdict"] == "too narrow", narrow[name]["reason"]
        assert "odometry" in narrow[name]["group"] and narrow[name]["factor"] > 5.0
    right = _diagnoses(tmp_path / "right", tmp_path, "right")
    for name in ("ekf", "gtsam-batch"):
        assert right[name]["verdict"] == "consistent", right[name]["reason"]


def test_a_survey_with_two_ids_swapped_is_named_by_id():
    """Thirty landmarks mapped to 0.2 m, the survey's ids 13 and 17 exchanged: both far off, named
    as swapped, the alignment refitted without them (its RMS back to the map's noise); one landmark
    5 m off alone is far off but not swapped."""
    from workbench.experiments.omni import survey

    rng = np.random.default_rng(8)
    truth = rng.uniform(-50, 50, (30, 2))
    est = truth + rng.normal(0, 0.2, (30, 2))
    swapped = truth.copy()
    swapped[[3, 7]] = swapped[[7, 3]]
    found = survey.compare(est, swapped, np.arange(30) + 10)
    assert found["swapped"] == [[13, 17]] and found["far"] == [13, 17] and found["refit"] == [13, 17]
    assert found["rms_without_far"] < 0.4 and found["median"] < 0.4
    assert "ids 13 and 17 each sit at the other's surveyed place" in survey.describe(found)
    est[5] += [5.0, 0.0]
    found = survey.compare(est, truth, np.arange(30))
    assert found["far"] == [5] and found["swapped"] == []


def test_a_swapped_survey_on_a_log_is_named_and_marked(tmp_path):
    """A synthetic log whose survey swaps the two nearest well-seen landmarks: the batch's map names
    them swapped in the metrics JSON and the report, and the recording marks them."""
    from rerun.chunk import RrdReader

    sim = faults.simulate(faults.Faults(poses=1500))
    ids, counts = np.unique(sim["true_ids"], return_counts=True)
    seen = ids[counts >= 40]  # landmarks seen often enough to be mapped well
    pts = sim["landmarks"][seen]
    d = np.hypot(*(pts[:, None] - pts[None]).transpose(2, 0, 1)) + np.eye(len(seen)) * 1e9
    i, j = np.unravel_index(np.argmin(np.where(d > 4.0, d, 1e9)), d.shape)
    pair = sorted([int(seen[i]), int(seen[j])])
    faults.write(tmp_path / "log", faults.Faults(poses=1500, swap=tuple(pair)))
    out, rrd = tmp_path / "m.json", tmp_path / "m.rrd"
    r = cli("omni", "--scenario", "log", "--data", str(tmp_path / "log"), "--estimators", "gtsam-batch",
            "--out", str(rrd), "--metrics", str(out))
    assert r.returncode == 0, r.stderr
    found = json.loads(out.read_text())["estimators"]["gtsam-batch"]["survey"]
    assert pair in found["swapped"], found
    assert f"ids {pair[0]} and {pair[1]} each sit at the other's surveyed place" in r.stdout
    labels = [lab for chunk in RrdReader(str(rrd)).store().stream()
              if str(chunk.entity_path) == "/map/gtsam-batch/far_off"
              for row in chunk.to_record_batch().column("Points3D:labels").to_pylist() for lab in row or []]
    assert any(f"id {pair[0]}:" in lab and f"swapped with id {pair[1]}" in lab for lab in labels), labels


def test_the_whole_distribution_is_tested_not_its_mean():
    """Student-t (3 dof) innovations scaled to a mean NIS of 1: the mean passes, the Cramér-von Mises
    test of their distribution against chi-square does not, scaled or not; chi-square draws pass."""
    rng = np.random.default_rng(9)
    t = rng.standard_t(3, 3000) ** 2
    t /= t.mean()
    bad = noisefit.goodness_of_fit(t, np.ones(3000), 1.0)
    assert bad["gof_p"] < 1e-3 and bad["gof_scaled_p"] < 1e-3
    good = noisefit.goodness_of_fit(rng.chisquare(1, 3000), np.ones(3000), 1.0)
    assert good["gof_p"] > 0.01


def test_the_consistency_line_names_the_diagnosis_when_it_alone_decides():
    """An estimator no truth-free test judges (a smoother without innovations), its verdict the
    diagnosis's: the line says so rather than "not consistent ()"."""
    from workbench.metrics import tables

    d = {"verdict": "outliers", "consistent": False, "factor": None, "group": None, "tail_share": 0.16,
         "reason": "a tail", "groups": {}}
    stats = {"estimators": {"isam2": {"diagnosis": d, "consistent_without_truth": False}}, "metric_table": {}}
    text = "\n".join(tables.verdicts(stats))
    assert "without truth **not consistent** (the diagnosis: outliers" in text and "()" not in text
