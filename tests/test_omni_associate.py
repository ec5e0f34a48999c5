"""The omni association front end's track management (``omni/associate.py``): chi-square
merges of duplicates, M-of-N confirmation, rejection; association without simulation ids on
noise-free bearings and on the round images, against the simulation's ids."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from workbench.experiments.omni.algorithms import ekf, graph
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.imaging import associate as assoc
from workbench.experiments.omni.run import with_stage
from workbench.experiments.omni.scenario import observe, simulate


def _filter_with_map(points: list[tuple[float, float]], sd: float) -> ekf.BearingEkf:
    """A cloned-pose EKF at the origin (pose known to 1 cm, 0.1 deg) holding ``points`` as
    landmarks 0.., each with an independent isotropic ``sd``."""
    cfg = OmniConfig(duration=10.0, sigma_bearing_deg=0.3).validate()
    data = simulate(cfg, np.random.default_rng(0))
    shell = replace(data, landmarks=np.zeros((len(points), 2)), landmark_ids=np.arange(len(points)))
    f = ekf.BearingEkf(shell, cfg, "clone")
    f.x = np.concatenate([[0.0, 0.0, 0.0], np.ravel(points)])
    f.P = np.diag(np.concatenate([[1e-4, 1e-4, math.radians(0.1) ** 2], np.full(2 * len(points), sd**2)]))
    f.slot[:] = 3 + 2 * np.arange(len(points))
    return f


def _rays(landmark: np.ndarray, poses: np.ndarray, cov: np.ndarray) -> list[assoc.Ray]:
    """Noise-free sightings of ``landmark`` from ``poses`` (bearing (9))."""
    d = landmark[None, :] - poses[:, :2]
    b = np.arctan2(d[:, 1], d[:, 0]) - poses[:, 2]
    return [assoc.Ray(p, cov, float(x)) for p, x in zip(poses, b, strict=True)]


def test_duplicate_landmark_is_merged_by_its_covariance():
    """A landmark 5 cm from another, both known to 10 cm, is the same one by the 2-dof test
    of their difference (d2 = (0.05^2 + 0.02^2) / 0.02 = 0.145 < chi2_2(0.99) = 9.21); 2 m
    away it is not. Merged, the filter holds their equal-weight mean with half the variance."""
    f = _filter_with_map([(10.0, 0.0), (10.05, 0.02), (12.0, 0.0)], sd=0.1)
    d2 = assoc._difference_nis(f, np.array([3, 3, 5]), np.array([5, 7, 7]))
    assert np.allclose(d2, [(0.05**2 + 0.02**2) / 0.02, 2.0**2 / 0.02, (1.95**2 + 0.02**2) / 0.02], rtol=1e-12)
    assert assoc._most_alike(f, 0.99) == (0, 1)
    tr = assoc.Tracks(np.array([0, 1, 1, 2]), np.zeros(4, int), confirmed={1, 2}, born=3)
    tr.provisional[0] = [1, 0]
    assoc._merge_duplicates(f, tr, 0.99)
    assert f.slot[1] == -1 and len(f.x) == 3 + 4
    assert np.allclose(f.x[3:5], [10.025, 0.01]) and np.allclose(np.diag(f.P)[3:5], 0.1**2 / 2)
    assert tr.track.tolist() == [0, 0, 0, 2] and tr.merged == 1
    assert tr.confirmed == {0, 2} and not tr.provisional  # the confirmed younger confirms the older
    assert assoc._most_alike(f, 0.99) is None


def test_retired_track_joins_the_one_landmark_its_rays_agree_with():
    """Five noise-free rays of (10, 0) from poses along the x = -2..0 line agree with it
    (summed NIS ~ 0 against chi2_5(0.99) = 15.1); they agree as well with a landmark 5 cm
    away, so with both in the map the merge is ambiguous and refused; with the duplicate
    forgotten they join (10, 0). Rays of a line 3 m to the side agree with neither."""
    f = _filter_with_map([(10.0, 0.0), (10.05, 0.02), (6.0, 3.0)], sd=0.1)
    poses = np.column_stack([np.linspace(-2.0, 0.0, 5), np.linspace(0.5, 0.0, 5), np.zeros(5)])
    cov = np.diag([1e-4, 1e-4, math.radians(0.1) ** 2])
    rays = _rays(np.array([10.0, 0.0]), poses, cov)
    assert assoc.rays_nis(rays, *assoc._landmark(f, 0), f.r) < 1e-9
    assert assoc._agreeing(f, rays, 0.99) == -1  # two landmarks agree: no merge
    f.forget(1)
    assert f.slot[1] == -1 and len(f.x) == 3 + 4 and f.slot[2] == 5
    assert assoc._agreeing(f, rays, 0.99) == 0
    side = _rays(np.array([10.0, 3.0]), poses, cov)
    assert assoc.rays_nis(side, *assoc._landmark(f, 0), f.r) > 1e3
    assert assoc._agreeing(f, side, 0.99) == -1


def test_provisional_landmark_needs_m_of_n_hits():
    """M-of-N confirmation: a new landmark seen in the next 3 epochs it is predicted in view is
    confirmed; one predicted in view and not seen 3 times (more than N - M = 2 misses) is
    taken out of the filter and its track retired; one out of view is not scored."""
    f = _filter_with_map([(10.0, 0.0), (0.0, 10.0), (-50.0, 0.0)], sd=0.1)
    cov = np.diag([1e-4, 1e-4, 1e-6])
    tr = assoc.Tracks(np.full(6, -1), np.full(6, -1), born=3)
    for lm in range(3):
        tr.rays[lm] = _rays(f.x[3 + 2 * lm:5 + 2 * lm], np.array([[0.0, -1.0, 0.0]]), cov)
        tr.provisional[lm] = [-1, 0]  # as _confirm leaves it, its own sighting scored next
    tr.track[0] = 0  # the epoch it entered the filter: its own sighting
    assoc._score_provisional(f, tr, np.array([0]), 30.0, 2 * np.pi, 0.99)
    assert tr.provisional == {0: [0, 0], 1: [-1, 1], 2: [-1, 0]}
    for epoch in (1, 2, 3):  # landmark 0 seen each epoch, 1 never, 2 beyond the 30 m range
        tr.track[epoch] = 0
        assoc._score_provisional(f, tr, np.array([epoch]), 30.0, 2 * np.pi, 0.99)
    assert tr.confirmed == {0} and 0 not in tr.rays
    assert f.slot[1] == -1 and tr.retired == [1]  # 3 misses: out of the filter, retired
    assert tr.provisional == {2: [-1, 0]} and f.slot[2] >= 0


def _noise_free(duration: float) -> tuple[OmniConfig, object, np.ndarray]:
    """The simulation's bearings without noise (odometry noisy), ids stripped; the front end
    told the image stage's 0.3 deg."""
    cfg = OmniConfig(duration=duration, sigma_bearing_deg=0.3).validate()
    data = simulate(cfg, np.random.default_rng(1))
    ms, ml, mb = observe(data.truth, data.landmarks, np.unique(data.meas_step), data.fov, data.max_range)
    return cfg, replace(data, meas_step=ms, meas_lm=np.zeros_like(ml), meas_bearing=mb), ml


def test_noise_free_bearings_are_all_associated_one_track_per_line():
    """120 s (a lap and a half): every detection goes to its own line's track, one track per
    line; the three lines glimpsed at the start and lost from view before they could be
    triangulated are merged into their landmarks when these are mapped on the next lap."""
    cfg, raw, truth_ids = _noise_free(120.0)
    a = assoc.associate(raw, cfg)
    owner = assoc.majority(a.track, truth_ids, a.n_tracks)
    assert (a.track >= 0).all()
    assert np.array_equal(owner[a.track], truth_ids)
    assert a.n_tracks == len(np.unique(truth_ids)) == len(raw.landmarks) == 32
    assert a.merged >= 3 and a.rejected == 0
    early = raw.t[raw.meas_step] < 5.0
    for lm in np.unique(truth_ids[early]):  # the early sightings share the later track
        assert len(np.unique(a.track[truth_ids == lm])) == 1


def _map_rmse(est, landmarks: np.ndarray) -> float:
    e = np.hypot(*(est.final_map - landmarks).T)
    return float(np.sqrt(np.nanmean(e**2)))


def test_images_associate_without_duplicates_and_map_as_simulated_bearings():
    """Seed 6, 500 s of 320 px round images (the CLI's ``--from-images --seed 6`` run 0):
    at least 97 % of the detections go to their own line, at most lines + 2 tracks, no
    line with two tracks; the EKF's and the batch smoother's maps from the images are within
    1.5x of theirs from simulated bearings (same seed and odometry) at the bearing noise the
    image stage measured."""
    cfg = OmniConfig(seed=6, from_images=True).validate()
    data, stage = with_stage(cfg, 0)
    s = stage.stats
    assert s["association_rate"] >= 0.97
    assert s["tracks"] <= cfg.wall_lines + cfg.pillars + 2
    # each track's majority line (its landmark for scoring): all different, none missing
    assert np.isfinite(data.landmarks).all() and len(np.unique(data.landmarks, axis=0)) == s["tracks"]
    sim_cfg = OmniConfig(seed=6, sigma_bearing_deg=s["bearing_rmse"]).validate()
    sim, _ = with_stage(sim_cfg, 0)
    for run in (lambda d, c: ekf.run(d, c, "clone", "ekf"), lambda d, c: graph.batch(d, c, graph.keyframes(d, c))):
        img_map = _map_rmse(run(data, cfg), data.landmarks)
        sim_map = _map_rmse(run(sim, sim_cfg), sim.landmarks)
        assert img_map <= 1.5 * sim_map, (img_map, sim_map)

