"""Where the data cannot decide between the batch's answers (issue 36: "where the data cannot decide,
say so rather than return an answer").

The batch solves a second start only where the first one's fit fails its chi-square test
(:func:`.starts._best_start`), and keeps the answer of the lowest truncated cost on the data
(:func:`.gating.robust_cost`, the negative log-likelihood up to a constant). Two answers are told
apart by the data where the likelihood ratio between them is large; where it is small and the
answers lie far apart, beyond both their covariances, the lower cost is chance and the data have
not chosen a basin. The batch then says so (``SlamEstimate.undecided``, and its diagnosis's
verdict "undecided": :mod:`workbench.metrics.diagnosis`) and keeps the lower one's answer only to
be looked at.

The ratio is read with the noise scaled by the winner's own fit: the fits failed, so the assumed
noise is too narrow by about ``sqrt(chi2 / dof)``, and a cost difference shrinks by that factor
squared once the noise is right (the variance factor of a least-squares adjustment, Förstner 1979;
an approximation for a truncated cost, whose cap does not scale). ``RATIO``: Royall, *Statistical
Evidence: a Likelihood Paradigm* (1997), ch. 1, calls a likelihood ratio of 8 fairly strong and 32
strong evidence; 20 is between them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from workbench.estimation.metrics import chi2_quantile

RATIO = 20.0
"""Two answers whose likelihood ratio (with the noise scaled by the fit) is under this: neither is
the data's choice."""
APART = 0.999
"""Two answers lie far apart where the median gap of their poses (3 dof) or of their common
landmarks (2 dof), ``d' (P1 + P2)^-1 d``, is over this point of its chi-square."""


def _median_gap(a: np.ndarray, b: np.ndarray, pa: np.ndarray, pb: np.ndarray, angle: int | None) -> float:
    """The median over rows of ``d' (P_a + P_b)^-1 d``, ``d = a - b`` (its ``angle`` column wrapped);
    a covariance GTSAM could not give (NaN: the marginals of a singular graph, as a wrong basin's
    can be) counts as none, the other alone then; rows with neither are left out."""
    d = a - b
    if angle is not None:
        d[:, angle] = (d[:, angle] + math.pi) % (2 * math.pi) - math.pi
    fa, fb = np.isfinite(pa).all(axis=(1, 2)), np.isfinite(pb).all(axis=(1, 2))
    ok = np.isfinite(d).all(axis=1) & (fa | fb)
    if not ok.any():
        return float("nan")
    s = np.where(fa[:, None, None], pa, 0.0)[ok] + np.where(fb[:, None, None], pb, 0.0)[ok]
    return float(np.median(np.einsum("ni,ni->n", d[ok], np.linalg.solve(s, d[ok][..., None])[..., 0])))


def between(names: Mapping[int, str], costs: Mapping[int, float], won: int, fit: tuple[float, int],
            answers: Mapping[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]) -> dict | None:
    """Whether the data leave the batch's choice open: the solved start of the smallest likelihood
    ratio to the winner ``won`` under :data:`RATIO` whose answer lies far from the winner's
    (:data:`APART`), as ``{starts, costs, ratio, scale, apart_m, pose_gap, landmark_gap}``; None
    where every other answer is beaten or is the same answer. ``names`` each solved start's name
    by its index, ``costs`` its truncated cost; ``fit`` the winner's ``(chi2, dof)``; ``answers``
    each solved start's ``(poses (E, 3), their world covariances (E, 3, 3), landmarks (N, 2) NaN where
    unmapped, their covariances (N, 2, 2))``."""
    chi2, dof = fit
    scale = max(1.0, chi2 / dof) if dof > 0 else 1.0
    poses, pcov, marks, mcov = answers[won]
    found = None
    for i in sorted(set(costs) - {won}):
        log_ratio = (costs[i] - costs[won]) / scale
        if log_ratio >= math.log(RATIO):
            continue
        p, pc, m, mc = answers[i]
        pose_gap = _median_gap(poses, p, pcov, pc, angle=2)
        landmark_gap = _median_gap(marks, m, mcov, mc, angle=None)
        far = (pose_gap > chi2_quantile(APART, 3)) or (landmark_gap > chi2_quantile(APART, 2))
        if far and (found is None or log_ratio < math.log(found["ratio"])):
            found = {"starts": [names[won], names[i]], "costs": [float(costs[won]), float(costs[i])],
                     "ratio": math.exp(log_ratio) if log_ratio < 700 else math.inf, "scale": math.sqrt(scale),
                     "apart_m": float(np.sqrt(np.mean(np.sum((poses[:, :2] - p[:, :2]) ** 2, axis=1)))),
                     **{k: g if math.isfinite(g) else None for k, g in (("pose_gap", pose_gap),
                                                                         ("landmark_gap", landmark_gap))}}
    if found is not None:
        found["said"] = said(found)
    return found


def said(u: Mapping) -> str:
    """The batch's undecided choice in words (its diagnosis's reason)."""
    a, b = u["starts"]
    return (f"the data cannot decide: the answers from {a} and {b} cost {u['costs'][0]:.0f} and {u['costs'][1]:.0f}, "
            f"a likelihood ratio of {u['ratio']:.2g} (under {RATIO:g}; the noise scaled x{u['scale']:.2f} by the "
            f"fit), and lie {u['apart_m']:.2f} m apart, beyond both their covariances; {a}'s is shown, not chosen")
