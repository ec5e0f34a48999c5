"""A landmark placed where most of its own bearings disagree is placed again where most agree
(:func:`workbench.experiments.omni.algorithms.graph.relocation._relocate`): on a synthetic log with 5 %
of the ids misread (seed 1), landmarks that entered from misread rays sat metres off with their
own bearings gated out; the batch's map was 24 m RMS against a Cramér-Rao bound of 0.88 m."""

import numpy as np

from workbench import api
from workbench.experiments.omni import faults


def test_misread_landmarks_move_to_where_their_bearings_agree(tmp_path):
    faults.write(tmp_path, faults.Faults(misread=0.05, seed=1), force=True)
    e = api.run("omni", "log", data=str(tmp_path), estimators="gtsam-batch").metrics["estimators"]["gtsam-batch"]
    assert e["map_rmse"] < 2.0 * e["map_bound"], (e["map_rmse"], e["map_bound"])   # measured 1.02 against 0.88
    errors = np.array(list(e["survey"]["errors"].values()))
    assert errors.max() < 5.0 and e["landmarks"] >= 80   # no landmark left tens of metres off


def test_a_log_without_misreads_is_left_as_it_was(tmp_path):
    """Without misreads no landmark has most of its bearings left out: nothing moves (the map as
    the gate and LM leave it: 0.93 m against a bound of 1.19, 73 landmarks)."""
    faults.write(tmp_path, faults.Faults(), force=True)
    e = api.run("omni", "log", data=str(tmp_path), estimators="gtsam-batch").metrics["estimators"]["gtsam-batch"]
    assert e["map_rmse"] < e["map_bound"] and e["landmarks"] == 73


def test_chance_agreement_by_hand():
    """Rays pointing anywhere: of 5, the 10 pairs each meet, and one of the other 3 agrees with
    probability 1 - (1 - p)^3; of 4 all agreeing, 6 pairs and both others, p^2; 3 of 3, 3p."""
    from workbench.experiments.omni.algorithms.graph.landmarks import chance_agreement

    p = 0.0143
    assert abs(chance_agreement(5, 3, p) - 10 * (1 - (1 - p) ** 3)) < 1e-12
    assert abs(chance_agreement(4, 4, p) - 6 * p ** 2) < 1e-12
    assert abs(chance_agreement(3, 3, p) - 3 * p) < 1e-12
    assert chance_agreement(40, 36, p) < 1e-40


def test_ids_never_seen_are_not_mapped_from_misread_rays(tmp_path):
    """20 % of the ids misread: ids that are never seen get a few misread rays each, and three of
    five meet within the gate often enough; those are taken out (their agreement is chance), and
    the batch's map after the best rigid alignment (``benchmarks/misread_maps.py``'s test) is within
    2x its bound (measured 1.00 against 0.90; 56.7 m before). Unaligned it reads 2.20: since iSAM2
    re-gates at its passes (:class:`.pruned._Pruned`), the batch from iSAM2's answer costs 6,368 by
    the truncated cost against the grown start's 6,671 and is kept, 1.55 m off in position where the
    grown start's answer was 0.58 (1.34 unaligned): the data's cost cannot tell them apart here."""
    faults.write(tmp_path, faults.Faults(misread=0.20), force=True)
    e = api.run("omni", "log", data=str(tmp_path), estimators="gtsam-batch").metrics["estimators"]["gtsam-batch"]
    assert e["aligned_map_rmse"] < 2.0 * e["map_bound"], (e["aligned_map_rmse"], e["map_bound"])
    sim = faults.simulate(faults.Faults(misread=0.20))
    never = set(range(150)) - set(sim["true_ids"].tolist())
    mapped = {int(k) for k in e["survey"]["errors"]}
    assert not mapped & never, sorted(mapped & never)


def test_a_landmark_whose_range_a_misread_alone_gives_is_not_placed_there(tmp_path):
    """10 % of the ids misread (seed 0): landmark 87's true bearings come from five keyframes in a
    row, nearly parallel; a misread from 78 m away crosses them and alone gives the range (leverage
    0.97-1). Least squares put it 44 m off there; MSAC's consensus then moved it back to 2.8 m. Now
    it does not enter at all (:meth:`_Landmarks.trusted`): its id shows a misread and its range
    would rest on one unchecked ray, and no later sighting checks it. Every landmark mapped is within
    5 m, and the map within 2x its bound (measured 0.55 against 0.97; 0.68 before, 5.69 before MSAC)."""
    faults.write(tmp_path, faults.Faults(misread=0.10, seed=0), force=True)
    e = api.run("omni", "log", data=str(tmp_path), estimators="gtsam-batch").metrics["estimators"]["gtsam-batch"]
    assert e["aligned_map_rmse"] < 2.0 * e["map_bound"], (e["aligned_map_rmse"], e["map_bound"])
    errors = e["survey"]["errors"]
    assert "87" not in errors and len(errors) > 50 and max(map(float, errors.values())) < 5.0, errors


def test_truncated_cost_by_hand():
    """MSAC's cost: each squared residual capped at the tolerance's square."""
    from workbench.experiments.omni.algorithms.graph.relocation import _truncated

    assert abs(_truncated(np.array([0.01, -0.02, 0.5, -3.0]), 0.05) - (1e-4 + 4e-4 + 2 * 0.0025)) < 1e-15


def _bearing(pose, point):
    return np.arctan2(point[1] - pose[1], point[0] - pose[0]) - pose[2]


def test_data_snooping_rejects_the_one_bearing_a_place_rests_on_by_hand():
    """Three rays 8 deg apart at 10 m (range sd 1.8 m) and one from the side that carries the
    range alone (leverage 0.99). Misread to point 8 m farther, least squares put the landmark there
    with every bearing within 1.8 deg (under the gate); the three reject the fourth (its deleted
    residual at 4.2 sd) and the place goes back to theirs. Misread 3 m farther, within what the
    three can tell, it is not judged."""
    from workbench.experiments.omni.algorithms.graph.landmarks import refine, snooped

    poses = np.array([[-0.7, 0.0, 0.0], [0.0, 0.0, 0.0], [0.7, 0.0, 0.0], [20.0, 10.0, np.pi]])
    truth = np.array([0.0, 10.0])
    sigma = np.radians(1.0)
    for farther, rejected in ((8.0, True), (3.0, False)):
        bearings = np.array([_bearing(p, truth) for p in poses])
        bearings[3] = _bearing(poses[3], truth + [0.0, farther])
        fitted = refine(np.array([0.5, 11.0]), poses, bearings)
        assert abs(fitted[1] - 10.0 - farther) < 0.2   # least squares follows the fourth
        found = snooped(fitted, poses, bearings, sigma)
        if rejected:
            assert found is not None and found[0] == 3 and np.hypot(*(found[1] - truth)) < 1e-6
        else:
            assert found is None


def test_a_landmark_resting_on_one_misread_goes_back_to_its_own_rays(tmp_path):
    """5 % misread, seed 6: landmark 1's three true bearings and one misread from 105 m; least
    squares put it 26 m off with every bearing within the gate. Data snooping leaves the misread out;
    three rays of four agreeing is then what chance gives (:func:`_ghosts`), so the landmark leaves
    the map rather than sit 26 m off, and the map is within 2x its bound (measured 0.73 against
    0.95; 3.19 before)."""
    faults.write(tmp_path, faults.Faults(misread=0.05, seed=6), force=True)
    e = api.run("omni", "log", data=str(tmp_path), estimators="gtsam-batch").metrics["estimators"]["gtsam-batch"]
    assert e["aligned_map_rmse"] < 2.0 * e["map_bound"], (e["aligned_map_rmse"], e["map_bound"])
    assert max(map(float, e["survey"]["errors"].values())) < 10.0


def test_an_entry_waits_while_one_ray_alone_gives_its_place_by_hand():
    """By hand (:meth:`_Landmarks.trusted`): a landmark at (10, 0). Two true rays a keyframe apart,
    from (0, 0) and (0.2, 0), nearly parallel, and one from the side, from (10, -10) looking up:
    that one alone gives the range. Its leverage (J_i (J'J)^-1 J_i') is 0.9998 (uncontrolled), and
    with a fourth, disagreeing ray among those held (the id shows a misread) the entry waits. Three
    rays 120 deg apart around it, 10 m off, are each checked by the others (leverages 2/3 each, any
    rays' add up to 2): that entry is taken where the agreement is beyond chance (3 of 4 agree: with
    a tolerance of 1 deg in a field of 360 deg, p = 1/180, 6 x 2p = 0.067 > 0.01, it waits; 6 of 7
    agree: 21 x 5p^4 = 1e-7, taken). Where every held ray agrees and more than three are held,
    nothing is judged."""
    from workbench.experiments.omni.algorithms.graph import landmarks

    point = np.array([10.0, 0.0])
    side = np.array([[0.0, 0.0, 0.0], [0.2, 0.0, 0.0], [10.0, -10.0, np.pi / 2]])
    lever = landmarks._leverage(point, side)
    assert lever[2] > 0.999 and not landmarks.controlled(point, side)
    assert abs(lever.sum() - 2.0) < 1e-9
    around = np.array([[10.0 - 10 * np.cos(a), -10 * np.sin(a), a] for a in np.radians([0.0, 120.0, 240.0])])
    assert np.allclose(landmarks._leverage(point, around), 2 / 3) and landmarks.controlled(point, around)
    marks = landmarks._Landmarks(1, 0.01, np.radians(15.0), fov=2 * np.pi)
    tol = np.radians(1.0)
    four = np.vstack([side, [[5.0, 5.0, 0.0]]])
    assert not marks.trusted(point, four, np.array([True, True, True, False]), tol)
    spread = np.vstack([around, [[5.0, 5.0, 0.0]]])
    assert abs(landmarks.ray_chance(tol, 2 * np.pi) - 1 / 180) < 1e-12
    assert not marks.trusted(point, spread, np.array([True, True, True, False]), tol)   # 0.067: chance
    seven = np.vstack([around, around[:1] + [0, 1, 0], around[1:2] + [0, 1, 0], around[2:] + [0, 1, 0],
                       [[5.0, 5.0, 0.0]]])
    assert landmarks.chance_agreement(7, 6, 1 / 180) < 1e-6
    assert marks.trusted(point, seven, np.array([True] * 6 + [False]), tol)
    assert marks.trusted(point, np.vstack([side, side]), np.ones(6, bool), tol)   # uncontrolled, but not judged
    # three agreeing rays wait for a fourth while agreement means something; where the tolerance
    # spans the field of view (any ray agrees: MRCLAM 6 robot 1 after a blind stretch, 41 deg either
    # side in a field of 66) a fourth would agree as surely, and the three enter
    assert not marks.trusted(point, side, np.ones(3, bool), tol)
    assert landmarks.ray_chance(np.radians(181.0), 2 * np.pi) == 1.0
    assert marks.trusted(point, side, np.ones(3, bool), np.radians(181.0))
    assert not marks.trusted(point, four, np.array([True, True, True, False]), np.radians(181.0))   # a misread shows


def test_isam2_places_again_a_landmark_its_later_bearings_outvote(tmp_path):
    """iSAM2 (graph/relocation.py), 10 % misread ids, seed 1: landmark 122 entered where one misread
    from 140 keyframes before gives its range alone; its later true bearings, each left out by the
    gate, outvote that place and it is placed again by consensus. iSAM2's map was 7.5 m off against a
    bound of 0.85 m; now within 2x its bound, and the report names the landmark. A log without
    misreads: nothing placed again."""
    faults.write(tmp_path / "misread", faults.Faults(misread=0.10, seed=1), force=True)
    e = api.run("omni", "log", data=str(tmp_path / "misread"), estimators="isam2").metrics["estimators"]["isam2"]
    assert e["aligned_map_rmse"] < 2.0 * e["map_bound"]
    said = " ".join(e["diagnosis"].get("remarks", []))
    assert "placed" in said and "122 at" in said
    faults.write(tmp_path / "clean", faults.Faults(seed=1), force=True)
    e = api.run("omni", "log", data=str(tmp_path / "clean"), estimators="isam2").metrics["estimators"]["isam2"]
    assert not e["diagnosis"].get("remarks")
