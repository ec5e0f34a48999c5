"""The GTSAM baseline: iSAM2's causal estimate against the causal MAP, factors shared."""

from dataclasses import replace

import gtsam
import numpy as np
from gtsam.symbol_shorthand import P, V

from workbench.experiments.sea import run
from workbench.experiments.sea.algorithms import smoother


def prefix_map(data, cfg, factors, K):
    """The causal MAP at step K: Levenberg-Marquardt to convergence over steps 0..K only (the
    camera's offset from the fixes up to K added, as iSAM2's estimate has it)."""
    graph = gtsam.NonlinearFactorGraph()
    init = gtsam.Values()
    pos, vel = factors.initial
    for f in smoother._priors(cfg, 0):
        graph.add(f)
    for k in range(K + 1):
        graph.add(factors.camera[k])
        if k < K:
            graph.add(factors.moves[k])
        init.insert(P(k), np.array([*pos[k], 0.0]))
        init.insert(V(k), np.array([*vel[k], 0.0]))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(2000)
    params.setRelativeErrorTol(1e-10)
    params.setAbsoluteErrorTol(1e-12)
    result = gtsam.LevenbergMarquardtOptimizer(graph, init, params).optimize().atPoint3(P(K))[:2]
    return result + factors.observer.offset[K]


def test_isam2_newest_estimate_is_the_causal_map(paper_cfg):
    """Once the range is observable (from about 20 s) iSAM2's newest step is the MAP of the data
    so far, to centimetres: its relinearisation and wildfire thresholds cost no accuracy."""
    cfg = replace(paper_cfg, estimators=("isam2",))
    data = run.make_data(cfg, 1)
    factors = smoother.FactorSet(data, cfg)
    est = smoother.incremental(data, cfg, factors=factors)
    ks = (300, 400, 500, 600, 700)
    dist = np.array([np.hypot(*(est.position[K] - prefix_map(data, cfg, factors, K))) for K in ks])
    assert dist.mean() < 0.05 and dist.max() < 0.1


def test_the_batch_marginals_by_cholesky_are_the_qr_ones(paper_cfg):
    """The batch smoother's covariances (GTSAM's ``Marginals``, Cholesky) are those of an iSAM2 with
    QR seeded at the same solution (the fallback where Cholesky fails), to 1e-5 of each standard
    deviation product, on two paper runs; and the motion factors a later run reuses are the very
    factors built for the first (the per-process cache), equal to freshly built ones."""
    cfg = replace(paper_cfg, estimators=("gtsam",))
    for r in (1, 2):
        data = run.make_data(cfg, r)
        factors = smoother.FactorSet(data, cfg)
        graph = gtsam.NonlinearFactorGraph()
        init = gtsam.Values()
        for f in smoother._priors(cfg, 0):
            graph.add(f)
        pos, vel = factors.initial
        for k in range(data.steps):
            if factors.camera[k] is not None:
                graph.add(factors.camera[k])
            if k + 1 < data.steps:
                graph.add(factors.moves[k])
            init.insert(P(k), np.array([*pos[k], 0.0]))
            init.insert(V(k), np.array([*vel[k], 0.0]))
        result = gtsam.LevenbergMarquardtOptimizer(graph, init, gtsam.LevenbergMarquardtParams()).optimize()
        chol = smoother.marginal_covariances(graph, result, data.steps)
        qr = smoother.marginal_covariances_qr(graph, result, data.steps)
        sd = np.sqrt(np.einsum("kii->ki", qr))
        assert np.max(np.abs(chol - qr) / (sd[:, :, None] * sd[:, None, :])) < 1e-5
    again = smoother.FactorSet(data, cfg)
    assert all(a is b for a, b in zip(again.moves, factors.moves, strict=True))
    fresh = smoother.MotionModel(data.dt, data.sigma_acc)
    x = gtsam.Values()
    rng = np.random.default_rng(5)
    for k in (P(7), V(7), P(8), V(8)):
        x.insert(k, rng.normal(size=3))
    assert abs(again.moves[7].error(x) - fresh.factor(7).error(x)) <= 1e-12 * fresh.factor(7).error(x)
