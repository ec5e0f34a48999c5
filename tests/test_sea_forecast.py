"""The l-step forecasts: none before the AR model exists, unusable ones counted, robust figures."""

import json
from dataclasses import replace

import numpy as np
import pytest

import workbench
from workbench.estimation.angles import from_arcmin
from workbench.experiments.sea import evaluate, report, run
from workbench.experiments.sea.algorithms import ar_filter
from workbench.experiments.sea.estimate import Estimate


def test_no_ar_forecast_before_the_model_exists(paper_cfg):
    data = run.make_data(paper_cfg, 0)
    est, ahead = ar_filter.filter_angle(data.beta_meas, paper_cfg.order_beta, paper_cfg, False)
    n = paper_cfg.order_beta
    assert np.all(np.isnan(ahead[:n])) and np.all(np.isfinite(ahead[n:]))
    np.testing.assert_array_equal(est[:n], data.beta_meas[:n])  # passed through


def test_forecast_errors_flag_elevations_above_the_horizon(paper_cfg):
    data = run.make_data(replace(paper_cfg, duration=1.0), 0)
    T, L = data.steps, 2
    angles = np.stack([data.alpha, data.beta], axis=-1)[:, None, :].repeat(L, axis=1)
    angles[:, 1, :] = np.roll(angles[:, 1, :], -L, axis=0)  # exact L-step forecasts ...
    angles[3, 1, 1] = -from_arcmin(1.0)                    # ... but one above the horizon
    forecast = np.full((T, L, 2), np.nan)
    forecast[: T - L, 1] = data.target[L:, :2] + [3.0, -4.0]
    forecast[3, 1] = np.nan
    est = Estimate("rls", data.target[:, :2], data.alpha, data.beta, data.range,
                   forecast=forecast, forecast_angles=angles)
    err, unusable = evaluate.forecast_errors(data, est)
    assert np.flatnonzero(unusable).tolist() == [3]
    np.testing.assert_allclose(err[: T - L][np.arange(T - L) != 3, :2], [[-3.0, 4.0]] * (T - L - 1))
    np.testing.assert_allclose(err[: T - L][np.arange(T - L) != 3, 2:], 0.0, atol=1e-15)
    assert np.isnan(err[3, :2]).all() and err[3, 3] == pytest.approx(data.beta[5] + from_arcmin(1.0))
    assert np.isnan(err[T - L:]).all()


def test_forecast_figures_are_robust_and_counted(paper_cfg):
    """Five seeded runs: the AR forecasts' RMSE is ruled by a few early fits, the median not."""
    cfg = replace(paper_cfg, runs=5, estimators=("rls", "window-rls", "ekf"))
    stats = workbench.run("sea", config=cfg, jobs=1).metrics
    json.dumps(stats, allow_nan=False)  # strict JSON: overflowing RMSEs are null, not Infinity
    T, L, n = stats["steps"], cfg.horizon, cfg.order_alpha
    for name in ("rls", "window-rls"):
        f = stats["estimators"][name]["forecast"]
        assert f["count"] == cfg.runs * (T - L - n)
        assert 0 < f["unusable"] < 0.01 * f["count"]
        assert f["position"]["median"] < 15.0 and f["position"]["p90"] < 60.0
        assert f["alpha"]["median_abs"] < 10.0 and f["beta"]["median_abs"] < 1.5
        assert f["position"]["rmse"]["y"] > f["position"]["p90"]  # outliers: why the median
    ekf = stats["estimators"]["ekf"]["forecast"]
    assert ekf["count"] == cfg.runs * (T - L) and ekf["unusable"] == 0 and "alpha" not in ekf
    assert ekf["position"]["median"] < 3.0
    text = report.table(stats)
    assert "unusable (beta <= 0)" in text and "position error median" in text
