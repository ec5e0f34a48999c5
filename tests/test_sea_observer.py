"""The camera held as one offset learnt from every fix (``workbench.experiments.sea.observer``,
issue 27 item 5): the separation is exact (an EKF with the offset in its state and a graph with an
offset variable shared by every bearing factor give the same estimates as the estimators that run
in the platform's frame and add the offset), the model is the data's, and with it the smoother
meets its bound and every model-based estimator's azimuth is at its bound (it was 2.5-4.9 times)."""

from dataclasses import replace

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import O, P, V

import workbench
from workbench.estimation import kalman
from workbench.estimation.angles import wrap
from workbench.experiments.sea import geometry, observer, run
from workbench.experiments.sea.algorithms import ekf, smoother
from workbench.experiments.sea.config import SeaConfig

SHORT = SeaConfig(duration=30.0).validate()


def test_the_offset_is_the_mean_of_the_fixes_on_the_dead_reckoned_path(paper_cfg):
    data = run.make_data(paper_cfg, 0)
    cam = observer.camera(data)
    T = data.steps
    assert cam.offset_model and cam.fold == 0.0
    np.testing.assert_allclose(cam.path, data.observer - data.observer[0], atol=1e-9)  # the true path, from its start
    np.testing.assert_allclose(cam.offset[4], (data.observer_meas[:5] - cam.path[:5]).mean(axis=0))
    np.testing.assert_allclose(cam.variance, data.sigma_observer**2 / np.arange(1, T + 1))
    # the whole run's fixes give the start to sigma / sqrt(T): 3.7 cm here
    assert np.all(np.abs(cam.offset[-1] - data.observer[0]) < 4 * data.sigma_observer / np.sqrt(T))
    exact = run.make_data(replace(paper_cfg, sigma_observer=0.0), 0)   # a camera known exactly: its start, exactly
    cam0 = observer.camera(exact)
    assert np.allclose(cam0.offset, exact.observer[0], atol=1e-9) and not cam0.variance.any()
    # without a known velocity (a log whose velocity is its fixes' gradient) the fixes stand alone, folded in
    folded = observer.camera(replace(data, velocity_known=False))
    assert not folded.offset_model and folded.fold == data.sigma_observer**2
    assert np.array_equal(folded.path, data.observer_meas) and not folded.offset.any()


def augmented_ekf(data, cfg):
    """The EKF with the camera's start ``c`` in its state, ``[x, y, vx, vy, cx, cy]``: the camera at
    ``c + d_k``, each step's fix ``m_k - d_k = c + n_k``, the angles of ``x - c - d_k``; ``c`` diffuse
    (1e4 m, the bound's prior) until the fixes come; the object started at its first seen step from
    (3)-(5) seen from the camera as then estimated."""
    T = data.steps
    d = observer.dead_reckoning(data)
    F = np.eye(6)
    F[:4, :4] = kalman.cv_transition(data.dt)
    Q = np.zeros((6, 6))
    Q[:4, :4] = kalman.cv_noise_discrete(data.dt, data.sigma_acc)
    Hc = np.zeros((2, 6))
    Hc[:, 4:] = np.eye(2)
    Rc = data.sigma_observer**2 * np.eye(2)
    R0 = np.diag([data.sigma_alpha**2, data.sigma_beta**2])
    x, P = np.zeros(6), np.diag([0, 0, 0, 0, 1e8, 1e8]).astype(float)
    started = False
    X, Ps = np.full((T, 4), np.nan), np.full((T, 4, 4), np.nan)
    for k in range(T):
        if k:
            x, P = kalman.predict(x, P, F, Q)
        x, P, _ = kalman.update(x, P, data.observer_meas[k] - d[k] - Hc @ x, Hc, Rc)
        if data.seen[k]:
            o = x[4:] + d[k]
            if not started:  # the object from (3)-(5) relative to the camera: its error is the angles' and c's
                started = True
                e0, Pe = ekf.initial_state(data, k, cfg.prior_speed, observer.Camera(d, 0 * d, 0 * d[:, 0], 0.0))
                x[:4] = e0 + np.r_[x[4:], 0.0, 0.0]
                A = np.zeros((6, 6))  # x = e + c: the object's covariance from e's and c's
                A[:4, :4] = np.eye(4)
                A[:2, 4:] = np.eye(2)
                A[4:, 4:] = np.eye(2)
                B = np.zeros((6, 6))
                B[:4, :4], B[4:, 4:] = Pe, P[4:, 4:]
                P = A @ B @ A.T
            else:
                J = geometry.angle_jacobian(x[:2], o, data.height)
                H = np.zeros((2, 6))
                H[:, :2], H[:, 4:] = J, -J
                h = np.array(geometry.angles(x[:2], o, data.course[k], data.height))
                nu = np.array([wrap(data.alpha_meas[k] - h[0]), data.beta_meas[k] - h[1]])
                x, P, _ = kalman.update(x, P, nu, H, R0)
        if started:
            X[k], Ps[k] = x[:4], P[:4, :4]
    return X, Ps


def test_the_ekf_is_the_ekf_with_the_offset_in_its_state():
    data = run.make_data(replace(SHORT, scenario="track-loss"), 2)   # unseen steps: the fixes go on
    est = ekf.estimate(data, SHORT)
    X, Ps = augmented_ekf(data, SHORT)
    ok = np.isfinite(X[:, 0])
    assert ok.sum() > 200 and (~data.seen).any()
    np.testing.assert_allclose(est.position[ok], X[ok, :2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(est.velocity[ok], X[ok, 2:], rtol=0, atol=1e-6)
    np.testing.assert_allclose(est.state_cov[ok], Ps[ok], rtol=1e-6, atol=1e-9)


def offset_graph(data, cfg):
    """The smoother's graph with the camera's start as one variable: a Pose3 ``O`` (its rotation and
    height pinned) that every bearing factor shares through a fixed body-to-camera pose at ``d_k``
    (GTSAM's ``GenericProjectionFactorCal3_S2`` with ``body_P_sensor``) and each fix a prior on."""
    cam = observer.camera(data)
    f = smoother.FactorSet(data, cfg)
    cov = smoother.camera_noise(data, cam)
    graph, init = gtsam.NonlinearFactorGraph(), gtsam.Values()
    for fa in smoother._priors(cfg, 0):
        graph.add(fa)
    fix = gtsam.noiseModel.Diagonal.Sigmas(np.r_[1e-9, 1e-9, 1e-9, data.sigma_observer, data.sigma_observer, 1e-6])
    pos, vel = f.initial
    for k in range(data.steps):
        start = np.r_[data.observer_meas[k] - cam.path[k], 0.0]   # the fix, less the path: the start
        graph.add(gtsam.PriorFactorPose3(O(0), gtsam.Pose3(gtsam.Rot3(), start), fix))
        if data.seen[k]:
            rot = gtsam.Rot3(gtsam.Rot3.Yaw(data.course[k] + data.alpha_meas[k]).matrix() @ smoother._CAMERA_IN_BODY)
            body = gtsam.Pose3(rot, np.r_[cam.path[k], data.height])
            graph.add(gtsam.GenericProjectionFactorCal3_S2(np.array([0.0, np.tan(data.beta_meas[k])]),
                                                           gtsam.noiseModel.Gaussian.Covariance(cov[k]), O(0), P(k),
                                                           smoother._UNIT_K, body))
        if k + 1 < data.steps:
            graph.add(f.moves[k])
        init.insert(P(k), np.r_[pos[k], 0.0])
        init.insert(V(k), np.r_[vel[k], 0.0])
    init.insert(O(0), gtsam.Pose3())
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(1000)
    params.setRelativeErrorTol(1e-12)
    params.setAbsoluteErrorTol(1e-12)
    result = gtsam.LevenbergMarquardtOptimizer(graph, init, params).optimize()
    return np.array([result.atPoint3(P(k))[:2] for k in range(data.steps)]), result.atPose3(O(0)).translation()[:2]


def test_the_smoother_is_the_graph_with_an_offset_variable(paper_cfg):
    """On the whole paper run (on 30 s LM stops metres short along the range's flat valley, 0.06
    of the cost's 300, either way)."""
    data = run.make_data(paper_cfg, 3)
    est = smoother.batch(data, paper_cfg)
    X, c = offset_graph(data, paper_cfg)
    np.testing.assert_allclose(c, observer.camera(data).offset[-1], atol=1e-6)
    assert np.abs(est.position - X).max() < 1e-3   # 0.03 mm: LM's convergence


def test_a_camera_factor_alone_is_the_factor_sets(paper_cfg):
    data = run.make_data(paper_cfg, 0)
    f = smoother.FactorSet(data, paper_cfg)
    values = gtsam.Values()
    values.insert(P(5), np.array([350.0, 520.0, 0.0]))
    assert smoother.camera_factor(data, 5, False).error(values) == pytest.approx(f.camera[5].error(values))


def test_the_smoother_meets_its_bound_and_the_azimuth_its_own():
    """24 seeded paper runs: the smoother's position efficiency is within 1.2 (1.04 here; 1.51 +- 0.19
    on 20 runs and 1.70 on 100 before), the EKF's and both azimuths within 1.1 (1.02, 1.01 and
    1.02 here; 1.12, 2.5 and 4.9 before); none below 1 beyond the Monte Carlo error."""
    res = workbench.run("sea", runs=24, jobs=1, estimators=["ekf", "gtsam"])  # (isam2: test_sea_smoother)
    e = res.metrics["estimators"]
    for name, s in e.items():
        for q in ("position", "alpha", "beta", "range"):
            eff, se = s[f"{q}_efficiency"], s[f"{q}_efficiency_se"]
            assert eff + 3 * se >= 1.0, (name, q, eff, se)
            assert eff - 2 * se <= (1.2 if name == "gtsam" and q != "alpha" else 1.1), (name, q, eff, se)
    assert e["gtsam"]["position_efficiency"] < 1.2


@pytest.mark.parametrize("sigma", [0.0, 3.0])
def test_the_camera_noise_moves_the_estimates_only_by_the_offset(sigma):
    """The camera's noise changes nothing but the offset the fixes give (and its variance): the
    relative track is the exact model's (``--sigma-observer 0``), to the last digit."""
    cfg = replace(SHORT, sigma_observer=sigma)
    data, exact = run.make_data(cfg, 1), run.make_data(replace(SHORT, sigma_observer=0.0), 1)
    exact = replace(exact, alpha_meas=data.alpha_meas, beta_meas=data.beta_meas)   # the same angles
    cam, cam0 = observer.camera(data), observer.camera(exact)
    for fn in (ekf.estimate, smoother.incremental):
        a, b = fn(data, cfg), fn(exact, cfg)
        np.testing.assert_allclose(a.position - cam.offset, b.position - cam0.offset, atol=1e-9)
        np.testing.assert_allclose(a.alpha, b.alpha, atol=1e-12, equal_nan=True)
