"""A graph smoother's residuals at its answer, by group, for the truth-free diagnosis
(:class:`~workbench.estimation.consistency.Residuals`, :mod:`workbench.metrics.diagnosis`).

Rows: each odometry factor between keyframes (3 dof, its squared whitened residual at the answer)
and each bearing of a landmark in the map (1 dof, ``(wrap(z - h(x)) / sigma)^2`` at the answer,
the bearing's own residual whatever robust kernel the graph gave it), the bearings a gate left out
among them (not used; their residual is still the answer's). Each group's redundancy is its used
residuals' dimension less its hat matrix's trace (:func:`~workbench.estimation.redundancy.hat_traces`).
"""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.estimation.angles import wrap
from workbench.estimation.consistency import Residuals
from workbench.estimation.redundancy import hat_traces


def of_graph(graph: gtsam.NonlinearFactorGraph, result: gtsam.Values, kf, inserted: np.ndarray,
             rejected: set[tuple[int, int]], gate: float | None) -> Residuals:
    """The residuals of a smoother whose answer ``result`` is over ``graph`` (prior, odometry
    between keyframes, the bearings kept), with ``kf`` the keyframes' bearings, ``inserted`` the
    landmarks in the map, ``rejected`` the ``(keyframe, landmark)`` bearings a gate left out and
    ``gate`` its probability (None: no gate)."""
    # the graph is the prior, the odometry between keyframes, then the bearings (:func:`.graph._batch_graph`)
    n_odo = sum(1 for k in range(1, min(graph.size(), len(kf.steps)))
                if isinstance(graph.at(k), gtsam.BetweenFactorPose2))
    groups = ["prior"] + ["odometry"] * n_odo + ["bearing"] * (graph.size() - 1 - n_odo)
    dims = [3] * (1 + n_odo) + [1] * (graph.size() - 1 - n_odo)
    group = ["odometry"] * n_odo
    r2 = [2.0 * graph.at(k).error(result) for k in range(1, 1 + n_odo)]
    dof, used = [3] * n_odo, [True] * n_odo
    e_of, lm_of, r2b = bearing_residuals(kf, result, inserted)
    ok = np.array([(int(e), int(lm)) not in rejected for e, lm in zip(e_of, lm_of, strict=True)], bool)
    group += ["bearing"] * len(r2b)
    r2 += r2b.tolist()
    dof += [1] * len(r2b)
    used += ok.tolist()
    kept_bearings = int(ok.sum())
    traces = hat_traces(graph, result, groups, dims=dims)
    n_odo = 3 * groups.count("odometry")
    redundancy = {"odometry": n_odo - traces.get("odometry", n_odo),
                  "bearing": kept_bearings - traces.get("bearing", kept_bearings)}
    return Residuals(np.array(group, str), np.array(r2, float), np.array(dof, int), np.array(used, bool),
                     redundancy, gate, landmark=np.concatenate([np.full(len(group) - len(lm_of), -1), lm_of]))


def bearing_residuals(kf, result: gtsam.Values, inserted: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every keyframe bearing of a landmark in the map at the answer ``result``, at once (each
    keyframe's pose and each landmark's point read once): its keyframe, its landmark and its squared
    whitened residual ``(wrap(z - h(x)) / sigma)^2``."""
    E = len(kf.bearings)
    have = [e for e in range(E) if len(kf.bearings[e][0]) and result.exists(X(e))]
    poses = np.full((E, 3), np.nan)
    for e in have:
        p = result.atPose2(X(e))
        poses[e] = p.x(), p.y(), p.theta()
    points = np.full((len(inserted), 2), np.nan)
    for lm in np.flatnonzero(inserted):
        if result.exists(L(int(lm))):
            points[lm] = result.atPoint2(L(int(lm)))
    e_of = np.concatenate([np.full(len(kf.bearings[e][0]), e) for e in have]) if have else np.zeros(0, int)
    lm_of = np.concatenate([kf.bearings[e][0] for e in have]).astype(int) if have else np.zeros(0, int)
    z = np.concatenate([kf.bearings[e][1] for e in have]) if have else np.zeros(0)
    sigma = np.concatenate([kf.sigma(e) for e in have]) if have else np.zeros(0)
    mapped = np.isfinite(points[lm_of]).all(axis=1)
    e_of, lm_of, z, sigma = e_of[mapped], lm_of[mapped], z[mapped], sigma[mapped]
    p, q = poses[e_of], points[lm_of]
    predicted = np.arctan2(q[:, 1] - p[:, 1], q[:, 0] - p[:, 0]) - p[:, 2]
    return e_of, lm_of, (wrap(z - predicted) / sigma) ** 2
