"""A graph smoother's residuals at its answer, by group, for the truth-free diagnosis
(:class:`~workbench.estimation.consistency.Residuals`, :mod:`workbench.experiments.diagnosis`).

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
    groups, group, r2, dof, used = [], [], [], [], []
    for k in range(graph.size()):
        f = graph.at(k)
        if isinstance(f, gtsam.BetweenFactorPose2):
            groups.append("odometry")
            group.append("odometry")
            r2.append(2.0 * f.error(result))
            dof.append(3)
            used.append(True)
        else:
            groups.append("bearing" if isinstance(f, gtsam.BearingFactor2D) else "prior")
    kept_bearings = 0
    for e, (lms, bearings) in enumerate(kf.bearings):
        if not len(lms) or not result.exists(X(e)):
            continue
        p = result.atPose2(X(e))
        for lm, b, sigma in zip(lms.tolist(), bearings.tolist(), kf.sigma(e).tolist(), strict=True):
            if not inserted[lm] or not result.exists(L(lm)):
                continue
            q = result.atPoint2(L(lm))
            predicted = np.arctan2(q[1] - p.y(), q[0] - p.x()) - p.theta()
            group.append("bearing")
            r2.append(float(wrap(b - predicted) / sigma) ** 2)
            dof.append(1)
            ok = (e, lm) not in rejected
            used.append(ok)
            kept_bearings += ok
    traces = hat_traces(graph, result, groups)
    n_odo = 3 * groups.count("odometry")
    redundancy = {"odometry": n_odo - traces.get("odometry", n_odo),
                  "bearing": kept_bearings - traces.get("bearing", kept_bearings)}
    return Residuals(np.array(group, str), np.array(r2, float), np.array(dof, int), np.array(used, bool),
                     redundancy, gate)
