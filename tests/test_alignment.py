"""The best rigid alignment (Umeyama, as evo's ``evo_ape -a``): a known rotation and translation
recovered exactly; the TUM export checked against evo's own numbers, raw and aligned; a
trajectory right in shape but turned as a whole scores badly raw and perfectly aligned."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import workbench
from workbench.estimation.alignment import umeyama
from workbench.experiments.omni.readers import tum


def test_umeyama_recovers_a_rigid_motion():
    rng = np.random.default_rng(3)
    truth = rng.normal(size=(40, 2)) * 10
    c, s = np.cos(0.4), np.sin(0.4)
    estimate = (truth - [3.0, -2.0]) @ np.array([[c, -s], [s, c]])   # R(-0.4) (truth - t)
    a = umeyama(estimate, truth)
    assert a.rotation == pytest.approx(0.4, abs=1e-12) and np.allclose(a.translation, [3.0, -2.0])
    poses = np.column_stack([estimate, np.zeros(40)])
    assert np.allclose(a.apply(poses)[:, :2], truth) and np.allclose(a.apply(poses)[:, 2], 0.4)


def _evo_rmse(*args: str) -> float:
    exe = shutil.which("evo_ape") or str(Path(sys.executable).with_name("evo_ape"))
    out = subprocess.run([exe, "tum", *args], capture_output=True, text=True, check=True).stdout
    return float(re.search(r"rmse\s+([0-9.eE+-]+)", out).group(1))


def test_tum_export_matches_evo(tmp_path):
    res = workbench.run("omni", duration=60.0, runs=1, estimators="ekf,gtsam-batch",
                        extras={"export_tum": tmp_path})
    t_true, truth = tum.read_tum(tmp_path / "truth.tum")
    for name in ("ekf", "gtsam-batch"):
        t, pose = tum.read_tum(tmp_path / f"{name}.tum")
        ref = truth[np.searchsorted(t_true, t)]
        raw = np.sqrt(np.mean(np.sum((ref[:, :2] - pose[:, :2]) ** 2, axis=1)))
        a = umeyama(pose[:, :2], ref[:, :2])
        aligned = np.sqrt(np.mean(np.sum((ref[:, :2] - a.apply(pose)[:, :2]) ** 2, axis=1)))
        args = (str(tmp_path / "truth.tum"), str(tmp_path / f"{name}.tum"))
        assert _evo_rmse(*args) == pytest.approx(raw, rel=1e-5)
        assert _evo_rmse(*args, "-a") == pytest.approx(aligned, rel=1e-5)
        assert aligned <= raw
    assert res.metrics["estimators"]["ekf"]["rmse_aligned"]["position"] > 0


def turned(data, cfg):
    """The truth turned by 5 deg about the room's centre: right in shape, wrong as a whole."""
    from workbench.experiments.omni.estimate import SlamEstimate

    c, s = np.cos(np.radians(5.0)), np.sin(np.radians(5.0))
    xy = (data.truth[:, :2] - 40.0) @ np.array([[c, s], [-s, c]]) + 40.0
    return SlamEstimate(pose=np.column_stack([xy, data.truth[:, 2] + np.radians(5.0)]))


def test_a_turned_trajectory_is_right_once_aligned():
    res = workbench.run("omni", duration=60.0, runs=2, estimators=["ekf", turned])
    e = res.metrics["estimators"]["turned"]
    assert e["rmse"]["position"] > 1.0 and e["rmse"]["heading"] == pytest.approx(5.0, abs=1e-6)
    assert e["rmse_aligned"]["position"] < 1e-9 and e["rmse_aligned"]["heading"] < 1e-9
    assert e["alignment"]["rotation_deg"] == pytest.approx(5.0, abs=1e-9)
    assert "after the best rigid alignment (evo -a)" in res.table
