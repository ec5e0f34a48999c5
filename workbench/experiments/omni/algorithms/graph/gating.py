"""The bearings' gate: a chi-square test of each bearing against the pose's and the landmark's
covariances (a contaminated Gaussian where an outlier rate is set), the bearings an answer leaves
out, and the cost by which starts are compared: the odometry's squared residuals plus every
bearing's, truncated at the gate (truncated least squares), so that no solution looks cheap by
leaving bearings out."""

from __future__ import annotations

import math
from collections.abc import Callable

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L

from workbench.estimation import outliers
from workbench.estimation.angles import wrap
from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms.graph.keyframes import Keyframes, _odometry_graph, poses_of
from workbench.experiments.omni.algorithms.graph.landmarks import AGREEING
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData


def outlier_rate(cfg: OmniConfig) -> float:
    """The bearings' outlier share the estimators assume (``assume_outlier_rate``; 0: none)."""
    return float(cfg.assume_outlier_rate or 0.0)


def gated(cfg: OmniConfig) -> bool:
    """Whether the graphs gate their bearings: a chi-square gate (``nis_gate``) or an outlier model."""
    return cfg.nis_gate > 0.0 or outlier_rate(cfg) > 0.0


def gate_of(cfg: OmniConfig) -> Callable[[np.ndarray | float], np.ndarray | float]:
    """The normalised squared bearing residual beyond which the graphs leave a bearing of
    variance ``s`` out, as a function of ``s``: the outlier model's even odds
    (:func:`workbench.estimation.outliers.even_odds`) where the config assumes one, else the
    chi-square gate ``nis_gate`` (inf where it is off), made once for a pass over the bearings."""
    rate = outlier_rate(cfg)
    if rate > 0.0:
        return lambda s: outliers.even_odds(s, rate)
    chi2 = chi2_quantile(cfg.nis_gate, 1) if cfg.nis_gate > 0.0 else math.inf
    return lambda s: chi2


def gate_nis(cfg: OmniConfig, s: np.ndarray | float) -> np.ndarray | float:
    """:func:`gate_of`'s threshold at ``s``."""
    return gate_of(cfg)(s)


def robust_cost(data: OmniData, cfg: OmniConfig, kf: Keyframes, result: gtsam.Values, inserted: np.ndarray
                ) -> float:
    """The data's cost under a solution, the same for every start whatever it left out: the prior's
    and the odometry factors' errors (half their squared Mahalanobis norms) plus, for every bearing
    at a keyframe, half its squared normalised residual truncated at the gate's chi-square
    quantile (``nis_gate``, 0.99 where the gate is off; with an outlier model its even odds,
    :func:`gate_of`, where the truncated cost is the mixture's likelihood's), a bearing of a landmark not in the map
    counting as one at the gate. Truncated least squares (Yang, Antonante, Tzoumas, Carlone,
    "Graduated non-convexity for robust spatial perception", RA-L 2020, eq. 3): a solution cannot
    lower its cost by leaving bearings out, each one out costs as much as the worst one kept, so
    a wrong basin that gates thousands of bearings out costs more than the right one.

    A landmark fewer than three of whose bearings fall under the cap counts every bearing of it at
    the cap, as one not in the map: two rays always meet, so a place only two agree on fits them
    for free (its two coordinates, their two residuals) and says nothing. Why: without it a start
    that maps every id two misread rays meet on costs less by two caps a ghost; on a drive with
    10 % of the ids misread (seed 6), dead reckoning's answer, with such a ghost 193 m off, cost
    4,675 against the grown graph's 4,824 and would have been kept (the batch's rule for entry, a
    third agreeing ray: :data:`.landmarks.AGREEING`)."""
    cost = _odometry_graph(data, kf).error(result)
    e = np.concatenate([np.full(len(lms), k) for k, (lms, _) in enumerate(kf.bearings)]).astype(int)
    lm = np.concatenate([lms for lms, _ in kf.bearings]).astype(int)
    b = np.concatenate([bs for _, bs in kf.bearings])
    sigma = np.concatenate(kf.sigmas) if kf.sigmas is not None else np.full(len(b), data.sigma_bearing)
    gate = (gate_of(cfg)(sigma ** 2) if outlier_rate(cfg) > 0.0
            else np.full(len(b), chi2_quantile(cfg.nis_gate if cfg.nis_gate > 0.0 else 0.99, 1)))
    mapped = inserted[lm]
    r2 = gate.copy()  # a bearing of a landmark not in the map counts at the gate
    if mapped.any():
        pose = poses_of(result, len(kf.steps))[e[mapped]]
        points = {k: result.atPoint2(L(k)) for k in np.unique(lm[mapped]).tolist()}
        d = np.array([points[k] for k in lm[mapped].tolist()]) - pose[:, :2]
        r = wrap(b[mapped] - (np.arctan2(d[:, 1], d[:, 0]) - pose[:, 2]))
        r2[mapped] = np.minimum(r * r / sigma[mapped] ** 2, gate[mapped])
        under = np.bincount(lm[mapped], weights=r2[mapped] < gate[mapped], minlength=len(inserted))
        alone = mapped & (under[lm] < AGREEING)
        r2[alone] = gate[alone]
    return float(cost + 0.5 * r2.sum())


def _bearing_test(pose: np.ndarray, pose_cov: np.ndarray, point: np.ndarray, point_cov: np.ndarray | None,
                  bearing: float, sigma: float) -> tuple[float, float]:
    """A bearing's squared residual from ``pose`` to ``point`` and its variance there: the pose's
    (world frame) and the point's covariance through the bearing's Jacobian (their correlation
    ignored; one not given or not finite left out) plus the bearing's own ``sigma^2``. A point on
    the pose has nothing to test: ``(0, 1)``."""
    d = np.asarray(point, float) - pose[:2]
    q = float(d @ d)
    if q < 1e-12:
        return 0.0, 1.0
    r = float(wrap(bearing - (math.atan2(d[1], d[0]) - pose[2])))
    s = sigma ** 2
    for h, cov in ((np.array([d[1] / q, -d[0] / q, -1.0]), pose_cov), (np.array([-d[1], d[0]]) / q, point_cov)):
        if cov is not None and np.isfinite(cov).all():
            s += float(h @ cov @ h)
    return r * r, s


def gated_indices(data: OmniData, kf: Keyframes, rejected: set[tuple[int, int]]) -> np.ndarray:
    """The dataset's indices of the bearings ``(keyframe, landmark)`` a gate left out."""
    if not rejected:
        return np.zeros(0, int)
    keys = {(int(kf.steps[e]), lm) for e, lm in rejected}
    pairs = zip(data.meas_step.tolist(), data.meas_lm.tolist(), strict=True)
    return np.array([i for i, key in enumerate(pairs) if key in keys], int)
