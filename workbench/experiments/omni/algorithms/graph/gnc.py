"""The batch's ``gnc`` start: graduated non-convexity (GTSAM's ``GncLMOptimizer``, truncated least
squares) over every bearing of the map, from the answer of the start solved before it.

Yang, Antonante, Tzoumas and Carlone, "Graduated non-convexity for robust spatial perception: from
non-minimal solvers to global outlier rejection", RA-L 2020: the truncated quadratic is reached
from its convex surrogate by raising a control parameter, each step a weighted least-squares solve
warm-started from the last, so a bearing's weight goes to 0 or 1 by the whole graph's evidence
rather than by one gate at one answer."""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L

from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms.graph.gating import gate_of
from workbench.experiments.omni.algorithms.graph.keyframes import Keyframes, _lm_params, poses_of
from workbench.experiments.omni.algorithms.graph.landmarks import _batch_graph, _Landmarks
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData

STEP = 3.0
"""GNC's factor on its control parameter per step (GTSAM's default 1.4). Measured on MRCLAM 6 robots
1, 2, 4 and 5 with 2 % misread ids (one sitting, under load): the truncated cost of the answer
within 1 % of 1.4's (783 against 776 at most), the whole refinement in a fifth to a half of the
time (6.6-10.7 s against 14.7-42.6 s)."""

INNER_ITERATIONS = 20
"""LM iterations in each of GNC's weighted solves (each warm-started from the last); 10 left the
answer up to 5 % costlier on the same logs (robot 2: 0.29 m off against 0.20)."""


def refine(data: OmniData, cfg: OmniConfig, kf: Keyframes, result: gtsam.Values, marks: _Landmarks,
           rejected: set[tuple[int, int]], *_: object) -> tuple[np.ndarray, np.ndarray, set[tuple[int, int]]]:
    """GNC from a solved start ``(result, marks, rejected)``: every bearing of a landmark in its map
    weighed again, the odometry and the prior known inliers, a bearing an inlier while its squared
    whitened residual is under the gate (:func:`.gating.gate_of` at the bearing's default sigma;
    ``nis_gate``'s chi-square, 0.99's where no gate is set). The weights start at the start's
    verdict (0 for what it left out), so GNC's first solve is the start's own answer. Returns
    ``(poses, landmarks, rejected)``: its answer at the keyframes, its map (NaN where not mapped),
    and the bearings of weight under 1/2."""
    graph = _batch_graph(data, kf, marks, set())
    params = gtsam.GncLMParams(_lm_params(INNER_ITERATIONS))
    params.setLossType(gtsam.GncLossType.TLS)
    params.setLambdaStep(STEP)
    bearing = [isinstance(graph.at(i), gtsam.BearingFactor2D) for i in range(graph.size())]
    params.setKnownInliers([i for i, b in enumerate(bearing) if not b])
    keys = {i: tuple(gtsam.Symbol(k).index() for k in graph.at(i).keys()) for i, b in enumerate(bearing) if b}
    weights = np.array([0.0 if b and keys[i] in rejected else 1.0 for i, b in enumerate(bearing)])
    optimizer = gtsam.GncLMOptimizer(graph, result, params)
    gate = float(gate_of(cfg)(data.sigma_bearing ** 2))
    optimizer.setInlierCostThresholds(0.5 * (gate if np.isfinite(gate) else chi2_quantile(0.99, 1)))
    optimizer.setWeights(weights)
    answer = optimizer.optimize()
    weights = np.asarray(optimizer.getWeights())
    out = set(rejected) | {keys[i] for i, b in enumerate(bearing) if b and weights[i] < 0.5}
    poses = poses_of(answer, len(kf.steps))
    landmarks = np.full((len(data.landmarks), 2), np.nan)
    for lm in np.flatnonzero(marks.inserted):
        landmarks[lm] = answer.atPoint2(L(int(lm)))
    return poses, landmarks, out
