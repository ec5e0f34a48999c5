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
