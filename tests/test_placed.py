"""The landmarks a map holds that its data cannot place (issue 36: "where the data cannot decide, say
so"): by the estimator's own covariance, the 95 % ellipse reaching further than the landmark's range."""

import json
import math
import types

import numpy as np
import pytest
from launcher import DATA, cli

from workbench.experiments.omni import placed
from workbench.experiments.omni.estimate import SlamEstimate


def test_a_landmark_whose_ellipse_reaches_past_its_range_is_not_placed():
    """By hand: two poses on the x axis see landmark 0 at (10, 0) and landmark 1 at (0, 10) (ids 7
    and 8). Landmark 0's sigma along its ray is 4.5 m: 2.448 x 4.5 = 11.0 m, past its median range
    (10 and 9 m from (0, 0) and (1, 0): 9.5 m), not placed; landmark 1's 1 m: placed."""
    data = types.SimpleNamespace(meas_step=np.array([0, 0, 5, 5]), meas_lm=np.array([0, 1, 0, 1]),
                                 landmark_ids=np.array([7, 8]))
    cov = np.array([np.diag([4.5 ** 2, 0.01]), np.diag([1.0, 0.04])])
    est = SlamEstimate("x", np.array([0, 5]), np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), None,
                       np.array([5]), np.array([[[10.0, 0.0], [0.0, 10.0]]]), cov[None])
    found = placed.unplaced(data, est)
    reach = math.sqrt(-2 * math.log(0.05))
    assert found["ids"] == [7]
    assert found["reach"]["7"] == pytest.approx(reach * 4.5 / 9.5)
    assert found["reach"]["8"] == pytest.approx(reach * 1.0 / np.median([10.0, math.hypot(1, 10)]))
    assert placed.describe(found) == "the data cannot place id 7 (its 95 % ellipse 1.2x its range): too little parallax"
    assert placed.unplaced(data, SlamEstimate("x", np.array([0]), np.zeros((1, 3)))) is None


def test_a_landmark_seen_five_times_that_the_map_does_not_hold_is_named():
    """By hand: ids 7, 8 and 9; 8 seen five times and 9 four, neither in the map: 8 is named
    unmapped (seen MIN_SEEN = 5 times), 9 is not (too few bearings to say anything)."""
    data = types.SimpleNamespace(meas_step=np.zeros(11, int), meas_lm=np.array([0, 0] + [1] * 5 + [2] * 4),
                                 landmark_ids=np.array([7, 8, 9]))
    mean = np.array([[[10.0, 0.0], [np.nan, np.nan], [np.nan, np.nan]]])
    cov = np.array([[np.eye(2), np.full((2, 2), np.nan), np.full((2, 2), np.nan)]])
    est = SlamEstimate("x", np.array([0]), np.zeros((1, 3)), None, np.array([0]), mean, cov)
    found = placed.unplaced(data, est)
    assert found["unmapped"] == [8] and found["ids"] == []
    assert placed.describe(found) == ("1 id seen 5+ times not mapped (8): their bearings place them nowhere the "
                                      "estimator trusts")
    many = placed.describe({"ids": [], "reach": {}, "unmapped": list(range(10))})
    assert many.startswith("10 ids seen 5+ times not mapped (0, 1, 2, 3, 4, 5, 6, 7, ...)")


@pytest.mark.skipif(not (DATA / "mrclam6").is_dir(), reason="the real MRCLAM data are not here")
def test_on_mrclam_the_landmarks_the_ekf_cannot_place_are_its_worst(tmp_path):
    """MRCLAM 6 robot 1, no truth read to flag them: the EKF's landmarks it cannot place are the ones
    its map has furthest off the survey (measured: 0.53-4.3 m against 0.25-0.40 m for the rest), and
    the smoothers, whose maps are right (0.21 m), place all theirs. The report says it, the recording
    rings them, labelled."""
    from rerun.chunk import RrdReader

    out, rrd = tmp_path / "m.json", tmp_path / "m.rrd"
    r = cli("omni", "--scenario", "mrclam", "--data", str(DATA / "mrclam6"), "--robot", "1", "--estimators",
            "ekf,gtsam-batch", "--out", str(rrd), "--metrics", str(out))
    assert r.returncode == 0, r.stderr
    got = json.loads(out.read_text())["estimators"]
    assert got["gtsam-batch"]["unplaced"]["ids"] == []
    ekf = got["ekf"]
    errors = ekf["survey"]["errors"]
    loose = set(map(str, ekf["unplaced"]["ids"]))
    assert loose and set(errors) - loose
    assert min(errors[i] for i in loose) > max(errors[i] for i in set(errors) - loose)
    assert placed.describe(ekf["unplaced"]) in r.stdout and "the data cannot place ids" in r.stdout
    labels = [lab for chunk in RrdReader(str(rrd)).store().stream() if str(chunk.entity_path) == "/map/ekf/unplaced"
              for row in chunk.to_record_batch().column("Points3D:labels").to_pylist() for lab in row or []]
    assert sorted(int(lab.split(":")[0][3:]) for lab in labels) == sorted(ekf["unplaced"]["ids"]), labels


def test_a_landmark_most_of_whose_own_bearings_miss_it_is_contradicted():
    """By hand, the bearings' median r2 at chi-square's median (0.455: their robust scale 1):
    landmark 0 has 6 bearings, 4 over 3 sigma off (r2 16 > 9): 4/6 miss it, contradicted; landmark 1
    has 20, 1 off: not; landmark 2 has 3 (under the 5 a median needs): not read. The odometry's rows
    (-1) are not a landmark's. Every r2 100 times larger (a noise told 10x too narrow): the same."""
    from scipy.stats import chi2

    from workbench.estimation.consistency import Residuals

    m = chi2.median(1)
    r2 = np.array([1.0, 2.0] + [16.0] * 4 + [m] * 2 + [25.0] + [m] * 19 + [30.0] * 3)
    lm = [-1, -1] + [0] * 6 + [1] * 20 + [2] * 3
    for k in (1.0, 100.0):
        res = Residuals(["odometry"] * 2 + ["bearing"] * 29, k * r2, [3, 3] + [1] * 29, [True] * 31,
                        {"odometry": 1.0, "bearing": 10.0}, landmark=lm)
        assert res.missed() == {0: pytest.approx(4 / 6), 1: pytest.approx(1 / 20)}
    est = types.SimpleNamespace(residuals=res)
    assert placed.contradicted(est, np.array([10, 11, 12])) == {"ids": [10], "missed": {"10": pytest.approx(4 / 6),
                                                                                        "11": pytest.approx(1 / 20)}}
    line = placed.describe({"ids": [], "reach": {}, "contradicted": [10], "missed": {"10": 4 / 6}})
    assert line == "id 10 contradicted by its own bearings (67 % over 3 sigma off): misread ids or a wrong basin"


def test_a_misread_ghost_is_named_and_the_batch_moves_it_where_its_bearings_agree(tmp_path):
    """A synthetic drive (3,000 poses, 150 landmarks) with 20 % of its bearings given another
    landmark's id, seed 5: iSAM2 puts id 39 over 100 m off the survey; most of its bearings miss it
    by over 3 sigma, so it is named contradicted (no truth read), the diagnosis says so and calls
    iSAM2 not consistent, and the recording rings it. The batch, which places a contradicted
    landmark again where most of its bearings agree, holds 39 within 10 m. (Seed 1's 10 %: iSAM2's
    id 122, 64 m off, is now placed again as its later bearings come, ``graph/relocation.py``;
    seed 0's ghosts 71, 32 and 52 no longer enter iSAM2's map: :meth:`_Landmarks.trusted`.) The same
    drive without misreads (seed 0): no landmark over 10 % missed (measured 0 %; the MRCLAM 6
    smoothers at most 23 %)."""
    from rerun.chunk import RrdReader

    from workbench import api
    from workbench.experiments.omni import faults

    for rate, where in ((0.20, tmp_path / "misread"), (0.0, tmp_path / "clean")):
        faults.write(where, faults.Faults(misread=rate, seed=5 if rate else 0), force=True)
        if rate:
            out, rrd = tmp_path / "m.json", tmp_path / "m.rrd"
            r = cli("omni", "--scenario", "log", "--data", str(where), "--estimators", "isam2,gtsam-batch",
                    "--out", str(rrd), "--metrics", str(out))
            assert r.returncode == 0, r.stderr
            got = json.loads(out.read_text())["estimators"]
            e = got["isam2"]
            assert 39 in e["unplaced"]["contradicted"] and e["survey"]["errors"]["39"] > 30.0
            assert any("rejected by their own measurements" in r for r in e["diagnosis"]["remarks"])
            assert e["diagnosis"]["consistent"] is False and placed.describe(e["unplaced"]) in r.stdout
            labels = [lab for chunk in RrdReader(str(rrd)).store().stream()
                      if str(chunk.entity_path) == "/map/isam2/contradicted"
                      for row in chunk.to_record_batch().column("Points3D:labels").to_pylist() for lab in row or []]
            assert sorted(int(lab.split(":")[0][3:]) for lab in labels) == sorted(e["unplaced"]["contradicted"])
            assert got["gtsam-batch"]["survey"]["errors"]["39"] < 10.0
        else:
            e = api.run("omni", "log", data=str(where), estimators="gtsam-batch").metrics["estimators"]["gtsam-batch"]
            assert e["unplaced"]["contradicted"] == [] and max(e["unplaced"]["missed"].values()) < 0.1
            assert not e["diagnosis"].get("remarks")
