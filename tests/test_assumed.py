"""What made the data apart from what the estimators assume (``--assume-sigma-*``): the data, the
truth and the bounds stay the data's; only the estimators see the assumed noise, so a
model-mismatch study is one sweep and a tuner varies only what they are told."""

import numpy as np
import pytest
from launcher import cli

import workbench


def test_the_sea_estimators_alone_are_told():
    base = workbench.run("sea", runs=2, duration=30.0)
    same = workbench.run("sea", runs=2, duration=30.0, assume_sigma_acc=0.1)   # the data's own: nothing changes
    told = workbench.run("sea", runs=2, duration=30.0, assume_sigma_acc=1.0)
    three = workbench.run("sea", runs=2, duration=30.0, assume_sigma_alpha_arcmin=2.64, assume_sigma_beta_arcmin=4.68,
                          assume_sigma_observer=3.0)
    assert np.array_equal(base.data.alpha_meas, told.data.alpha_meas) and told.data.sigma_acc == 0.1
    for name, est in base.estimates.items():
        assert np.array_equal(est.position, same.estimates[name].position, equal_nan=True), name
    assert not np.allclose(told.estimates["ekf"].position, base.estimates["ekf"].position)
    assert np.array_equal(told.estimates["geometric"].position, base.estimates["geometric"].position)
    e0, e1 = base.metrics["estimators"]["ekf"], told.metrics["estimators"]["ekf"]
    assert e1["position_bound"] == e0["position_bound"]          # the bound is the data's
    # told every measurement noise is 3x what it is, the filter's NIS (2 dof) falls to about 2/9:
    # the innovations' covariance is mostly the measurement's, now nine times too large
    assert 0.18 < three.metrics["estimators"]["ekf"]["nis"] < 0.3 and e0["nis"] == pytest.approx(2.0, abs=0.1)


def test_the_omni_estimators_alone_are_told():
    base = workbench.run("omni", runs=1, duration=60.0)
    told = workbench.run("omni", runs=1, duration=60.0, assume_sigma_bearing_deg=3.0)
    assert told.data.sigma_bearing == base.data.sigma_bearing
    e0, e1 = base.metrics["estimators"]["ekf"], told.metrics["estimators"]["ekf"]
    assert e1["position_bound"] == e0["position_bound"]
    # every bearing's variance told 9x what it is: the NIS drops towards 1/9 (the pose's share aside)
    assert e1["nis"] < 0.25 * e0["nis"]


@pytest.mark.parametrize("args,said", [
    (("sea", "--assume-sigma-acc", "0"), "--assume-sigma-acc must be a positive number"),
    (("sea", "--assume-sigma-alpha", "nan"), "--assume-sigma-alpha must be a finite number"),
    (("omni", "--assume-sigma-w", "2"), "--assume-sigma-w: this data's odometry is bicycle"),
    (("omni", "--assume-sigma-bearing", "-1"), "--assume-sigma-bearing must be a positive number"),
])
def test_bad_assumptions_are_one_line(tmp_path, args, said):
    r = cli(*args, "--runs", "1", "--duration", "5", "--out", str(tmp_path / "x.rrd"))
    assert r.returncode == 2 and said in r.stderr and "\n" not in r.stderr.strip() and "Traceback" not in r.stderr
    assert not (tmp_path / "x.rrd").exists()
