"""``--tune-noise``: the noise the data identify, found on the data by a filter's likelihood (no truth
read) and told to every estimator; the likelihood charges a gated measurement so gating never wins."""

import json
import math

import numpy as np
import pytest
from launcher import cli, wb

import workbench
from workbench.estimation.consistency import Innovations


def test_a_gated_measurement_is_charged_as_the_least_likely_kept_one():
    innov = Innovations.scalar(np.arange(4.0), np.array([1.0, np.nan, 2.0, 0.5]), np.array([1.0, np.nan, 4.0, 1.0]))
    term = [0.5 * (math.log(2 * math.pi) + math.log(s) + v * v / s) for v, s in ((1, 1), (2, 4), (0.5, 1))]
    assert np.allclose(innov.nll()[[0, 2, 3]], term) and np.isnan(innov.nll()[1])
    assert innov.charged_nll()[1] == pytest.approx(max(term))     # log 4 / 2 + 1 / 2 + log(2 pi) / 2


def test_the_sea_noise_is_found_from_ten_and_three_times_off():
    res = workbench.run("sea", runs=1, estimators=["ekf", "gtsam"], assume_sigma_acc=1.0,
                        assume_sigma_alpha_arcmin=2.64, assume_sigma_beta_arcmin=4.68, tune_noise=True)
    tuned = res.metrics["tuned_noise"]
    assert tuned["start"] == {"sigma_acc": 1.0, "sigma_alpha_arcmin": 2.64, "sigma_beta_arcmin": 4.68}
    # what made the data: 0.1 m/s^2, 0.88 and 1.56 arcmin, found within 25 % from the one run's likelihood
    # (measured: 0.093, 0.90, 1.54)
    assert tuned["tuned"]["sigma_acc"] == pytest.approx(0.1, rel=0.25)
    assert tuned["tuned"]["sigma_alpha_arcmin"] == pytest.approx(0.88, rel=0.25)
    assert tuned["tuned"]["sigma_beta_arcmin"] == pytest.approx(1.56, rel=0.25)
    assert tuned["nll_tuned"] < tuned["nll_start"] and tuned["evaluations"] <= 80
    # the camera's position noise: its fixes alone measure the offset, the angles' likelihood cannot see it
    assert list(tuned["left"]) == ["sigma_observer"]
    cfg = res.config                                      # what every estimator ran with, stored as is
    assert cfg.assume_sigma_acc == tuned["tuned"]["sigma_acc"] and cfg.tune_noise is False
    assert res.data.sigma_acc == 0.1                      # the data stay the data's
    assert res.metrics["estimators"]["ekf"]["nll"] == pytest.approx(tuned["nll_tuned"], rel=1e-9)


def test_where_the_camera_path_is_the_fixes_own_the_azimuth_is_left():
    """A log without the platform's velocity: the fixes' noise adds to the angles' (1 m at ~400 m is
    8.7 arcmin against the azimuth's 0.88): the azimuth's own noise is left, and why."""
    import dataclasses

    from workbench.experiments import get
    from workbench.experiments.sea import run

    exp = get("sea")
    cfg = exp.validate(exp.configure())
    data = dataclasses.replace(exp.dataset(cfg, 0), velocity_known=False)
    _, values, left = run.tunable(data, cfg)
    assert set(values) == {"sigma_acc", "sigma_beta_arcmin"} and "cannot separate them" in left["sigma_alpha_arcmin"]


def test_the_command_says_what_it_tuned_and_terrain_says_why_not(tmp_path):
    r = wb("sea", "--runs", "1", "--duration", "30", "--estimators", "ekf", "--tune-noise",
           "--out", str(tmp_path / "a.rrd"), "--metrics", str(tmp_path / "a.json"))
    assert r.returncode == 0, r.stderr
    assert "tuned noise (the likelihood of ekf's innovations on run 0" in r.stdout
    # the camera's start an offset the fixes measure: both angles' own noise is identified, and tuned
    assert set(json.loads((tmp_path / "a.json").read_text())["tuned_noise"]["tuned"]) == {
        "sigma_acc", "sigma_alpha_arcmin", "sigma_beta_arcmin"}
    r = cli("terrain", "--tune-noise", "--out", str(tmp_path / "t.rrd"))
    assert r.returncode == 2 and "terrain's estimators report no innovations" in r.stderr, r.stderr
    assert "\n" not in r.stderr.strip() and not (tmp_path / "t.rrd").exists()
