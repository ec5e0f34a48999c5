"""Equations against hand-derived cases, recursions against closed forms, noise-free runs."""

from dataclasses import replace

import numpy as np
import pytest

import workbench
from workbench.estimation import diffuse_rls as drls
from workbench.estimation import kalman, metrics
from workbench.estimation.angles import from_arcmin, to_arcmin, wrap
from workbench.experiments.sea import geometry, run
from workbench.experiments.sea.algorithms import ar_filter, ekf, geometric, smoother


def test_angles_hand_case():
    # target 100 m ahead and 100 m to the left of a camera heading along +x, h = 3 m
    a, b = geometry.angles(np.array([100.0, 100.0]), np.zeros(2), 0.0, 3.0)
    assert a == pytest.approx(np.pi / 4)
    assert b == pytest.approx(np.arctan(3.0 / np.hypot(100, 100)))
    # behind the camera: atan2 keeps the quadrant that atan(p/r) would lose
    a, _ = geometry.angles(np.array([-100.0, 1.0]), np.zeros(2), 0.0, 3.0)
    assert a == pytest.approx(np.pi - np.arctan(0.01))


def test_geometric_inverse_recovers_position(rng):
    target = rng.uniform(-800, 800, (50, 2))
    obs = rng.uniform(-50, 50, (50, 2))
    psi = rng.uniform(-np.pi, np.pi, 50)
    a, b = geometry.angles(target, obs, psi, 3.0)
    xy, d = geometry.position(a, b, obs, psi, 3.0)
    np.testing.assert_allclose(xy, target, atol=1e-8)
    np.testing.assert_allclose(d, np.hypot(*(target - obs).T), rtol=1e-12)


def test_angle_jacobian_matches_finite_differences():
    x, o, h = np.array([300.0, 500.0]), np.array([10.0, -4.0]), 3.0
    J = geometry.angle_jacobian(x, o, h)
    eps = 1e-4
    for i in range(2):
        dx = np.zeros(2)
        dx[i] = eps
        hp = np.array(geometry.angles(x + dx, o, 0.3, h))
        hm = np.array(geometry.angles(x - dx, o, 0.3, h))
        np.testing.assert_allclose(J[:, i], (hp - hm) / (2 * eps), rtol=1e-6)


def test_angle_units_and_wrap():
    assert to_arcmin(from_arcmin(0.88)) == pytest.approx(0.88)
    assert wrap(3 * np.pi) == pytest.approx(np.pi)
    assert wrap(-np.pi) == pytest.approx(np.pi)


def _ar_data(rng, T=300, gaps=True):
    y = np.empty(T)
    y[:2] = [0.1, 0.12]
    for t in range(2, T):
        y[t] = 1.6 * y[t - 1] - 0.64 * y[t - 2] + 0.01 + rng.normal(0, 0.01)
    if gaps:
        y[100:120] = np.nan
    return y


@pytest.mark.parametrize("lam", [1.0, 0.97])
def test_rls_closed_form_equals_recursion(rng, lam):
    y = _ar_data(rng)
    H = drls.regressors(y, 3, intercept=True)
    np.testing.assert_allclose(drls.rls_closed(H, y, lam), drls.rls_recursive(H, y, lam),
                               rtol=1e-6, atol=1e-9)


def test_window_rls_closed_form_equals_recursion(rng):
    y = _ar_data(rng, T=200)
    H = drls.regressors(y, 3, intercept=False)
    np.testing.assert_allclose(drls.window_rls_closed(H, y, 25), drls.window_rls_recursive(H, y, 25),
                               rtol=1e-6, atol=1e-9)


def test_diffuse_rls_exact_in_finite_steps_without_noise():
    # a noise-free sinusoid is exactly AR(2), y_t = 2 cos(w) y_{t-1} - y_{t-2}: the diffuse
    # algorithm recovers theta once W has full rank (two rows), unlike RLS with a finite prior
    w = 0.3
    y = np.sin(w * np.arange(40) + 0.2)
    H = drls.regressors(y, 2, intercept=False)
    truth = [2 * np.cos(w), -1.0]
    theta = drls.rls_recursive(H, y, 1.0)
    np.testing.assert_allclose(theta[3], truth, atol=1e-9)
    np.testing.assert_allclose(drls.window_rls_closed(H, y, 4)[-1], truth, atol=1e-9)


def test_forecast_matches_iterated_model():
    series = np.array([1.0, 2.0, 3.0, 4.0])
    theta = np.tile([2.0, -1.0], (4, 1))  # linear extrapolation
    f = ar_filter.forecast(series, theta, 2, False, 3)
    np.testing.assert_allclose(f[3], [5.0, 6.0, 7.0])


def test_chi2_band_and_nees():
    lo, hi = metrics.chi2_band(2, 1)
    assert lo == pytest.approx(0.0506, abs=1e-3) and hi == pytest.approx(7.378, abs=1e-3)
    assert metrics.nees(np.array([1.0, 2.0]), np.diag([1.0, 4.0])) == pytest.approx(2.0)


def test_joseph_update_keeps_covariance_symmetric_pd(rng):
    P = np.eye(4) * 100
    x = np.zeros(4)
    for _ in range(200):
        H = rng.normal(size=(2, 4))
        x, P, _ = kalman.update(x, P, rng.normal(size=2), H, np.eye(2) * 1e-8)
        x, P = kalman.predict(x, P, kalman.cv_transition(0.1), kalman.cv_noise_discrete(0.1, 0.1))
        assert np.allclose(P, P.T)
        assert np.linalg.eigvalsh(P).min() > 0


def _noise_free(cfg):
    cfg = replace(cfg, sigma_alpha_arcmin=1e-6, sigma_beta_arcmin=1e-6, sigma_observer=0.0,
                  sigma_acc=0.0)
    return cfg, run.make_data(cfg, 0)


def test_noise_free_geometric_and_smoother_hit_truth(paper_cfg):
    cfg, data = _noise_free(paper_cfg)
    g = geometric.estimate(data)
    np.testing.assert_allclose(g.position, data.target[:, :2], atol=1e-3)
    s = smoother.batch(data, cfg)
    assert np.max(np.abs(s.position - data.target[:, :2])) < 0.05


def test_noise_free_ar_filters_track_truth(paper_cfg):
    cfg, data = _noise_free(paper_cfg)
    for windowed in (False, True):
        e = ar_filter.estimate(data, cfg, windowed)
        err = to_arcmin(e.alpha - data.alpha)
        # a smooth angle is not exactly AR(5): the model error stays far below the 0.88' noise
        assert np.sqrt(np.mean(err**2)) < 0.05 and np.max(np.abs(err)) < 0.5


def test_algorithm1_reproduces_table2(paper_cfg):
    """Algorithm 1's RMSE within 10 % of the paper's 20.7 m / 31 m, angles equal to the noise."""
    cfg = replace(paper_cfg, runs=30, estimators=("geometric",))
    stats = workbench.run("sea", config=cfg, jobs=1).metrics["estimators"]["geometric"]
    assert stats["rmse"]["x"] == pytest.approx(20.7, rel=0.10)
    assert stats["rmse"]["y"] == pytest.approx(31.0, rel=0.10)
    assert stats["rmse"]["alpha"] == pytest.approx(0.88, rel=0.05)
    assert stats["rmse"]["beta"] == pytest.approx(1.56, rel=0.05)


def test_ekf_consistent_over_monte_carlo(paper_cfg):
    """The EKF's ANEES (4 states) inside the 95 % chi-square band over 20 seeded runs."""
    cfg = replace(paper_cfg, runs=20, estimators=("ekf",))
    stats = workbench.run("sea", config=cfg, jobs=1).metrics["estimators"]["ekf"]
    lo, hi = stats["anees_band"]
    assert lo < stats["anees"] < hi


def test_ekf_initial_covariance_is_pd(paper_cfg):
    data = run.make_data(paper_cfg, 0)
    _, P = ekf.initial_state(data, 0, 10.0)
    assert np.linalg.eigvalsh(P).min() > 0


def test_the_residual_of_an_estimate_that_used_the_measurement():
    """``r' (R - H P H')^-1 r``: by hand, and NaN where the estimate claims more than the
    measurement's noise (``R - H P H'`` indefinite); over seeded runs, the filters' and the
    smoother's residuals are chi-square with 2 dof (the 95 % band of the mean over the runs), the
    geometric inverse fits each measurement exactly (0), the RLS, without a covariance, a figure."""
    from workbench.estimation import consistency

    r = np.array([[1.0, 0.0], [1.0, 1.0]])
    R = np.stack([np.diag([2.0, 1.0])] * 2)
    HPH = np.stack([np.diag([1.0, 0.0]), np.diag([3.0, 0.0])])
    out = consistency.residual(r, R, HPH)
    assert out[0] == pytest.approx(1.0) and np.isnan(out[1])
    assert consistency.residual(r, R)[0] == pytest.approx(0.5)
    res = workbench.run("sea", runs=6, duration=30.0)
    e = res.metrics["estimators"]
    lo, hi = metrics.chi2_band(2, 6)
    for name in ("ekf", "gtsam", "isam2"):
        assert lo < e[name]["angle_residual"] < hi, (name, e[name]["angle_residual"])
    assert e["geometric"]["angle_residual"] < 1e-12 and e["rls"]["angle_residual"] > 0.1


def _reference_ekf(data, cfg):
    """The sea EKF as the textbook writes it: :func:`kalman.predict` and :func:`kalman.update`
    with ``H = [J, 0]`` from :func:`geometry.angle_jacobian`, R from :func:`geometry.effective_noise`."""
    from workbench.experiments.sea import observer

    F, Q = kalman.cv_transition(data.dt), kalman.cv_noise_discrete(data.dt, data.sigma_acc)
    gate = -2.0 * np.log1p(-cfg.ekf_gate)
    cam = observer.camera(data)
    X = np.full((data.steps, 4), np.nan)
    x = P = None
    for k in range(data.steps):
        if x is not None:
            x, P = kalman.predict(x, P, F, Q)
        if data.seen[k]:
            if x is None:
                x, P = ekf.initial_state(data, k, cfg.prior_speed, cam)
            else:
                o = cam.path[k]
                h = np.array(geometry.angles(x[:2], o, data.course[k], data.height))
                J = geometry.angle_jacobian(x[:2], o, data.height)
                H = np.hstack([J, np.zeros((2, 2))])
                R = geometry.effective_noise(x[:2], o, data.height, data.sigma_alpha, data.sigma_beta,
                                             np.sqrt(cam.fold), jacobian=J)
                nu = np.array([wrap(data.alpha_meas[k] - h[0]), data.beta_meas[k] - h[1]])
                S = H @ P @ H.T + R
                if cfg.ekf_gate <= 0 or nu @ np.linalg.solve(S, nu) <= gate:
                    x, P, _ = kalman.update(x, P, nu, H, R)
        if x is not None:
            X[k] = x
    return X[:, :2] + cam.offset if cam.offset_model else X[:, :2]


@pytest.mark.parametrize("scenario", ["paper", "impulse"])
def test_the_ekf_loop_is_the_textbook_ekf(scenario):
    """The EKF's scalar measurement model and closed-form 2x2 inverse give the textbook filter's
    estimates (kalman.predict / kalman.update, the geometry module's angles, Jacobian and noise) to
    rounding, with the gate on (impulse) and off (paper)."""
    cfg = workbench.configure("sea", scenario=scenario, estimators=["ekf"])
    data = run.make_data(cfg, 2)
    mine = ekf.estimate(data, cfg).position
    theirs = _reference_ekf(data, cfg)
    ok = np.isfinite(theirs[:, 0])
    assert np.isfinite(mine[ok]).all() and np.max(np.abs(mine[ok] - theirs[ok])) < 1e-9 * np.max(np.abs(theirs[ok]))
