"""The terrain experiment's metrics (:mod:`workbench.metrics.base`): each a function of a
run's dataset and one estimate, one value a run (the orientation of image II, the one the paper
corrects; errors ``truth - estimate``): the position error (3D norm) and its components, the
attitude error (the norm of the three angles), the halftone model's ground error, the paper's
Fig. 3 fractions of the maximum error, the NEES and the Cramér-Rao bounds.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from workbench.estimation import metrics as em
from workbench.estimation.angles import wrap
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.products import halftone
from workbench.experiments.terrain.scenario import TerrainData
from workbench.metrics.base import Metric, MetricContext, Values


def _position(data: TerrainData, est: Estimate) -> np.ndarray:
    return data.scene.position[1] - est.position[1]


def position_error(data: TerrainData, est: Estimate) -> Values:
    return Values([np.linalg.norm(_position(data, est))])


def attitude_error(data: TerrainData, est: Estimate) -> Values:
    return Values([np.linalg.norm(wrap(data.scene.angles[1] - est.angles[1]))])


def _component(i: int, fraction: bool = False):
    def fn(data: TerrainData, est: Estimate, ctx: MetricContext) -> Values:
        p = _position(data, est)
        return Values([abs(p[i]) / ctx.cfg.max_linear if fraction else p[i]])

    fn.__name__ = ("d{}_fraction" if fraction else "d{}").format("xyh"[i])
    return fn


def dr_fraction(data: TerrainData, est: Estimate, ctx: MetricContext) -> Values:
    p = _position(data, est)
    return Values([np.hypot(p[0], p[1]) / ctx.cfg.max_linear])


def truth_known(scene: Any) -> bool:
    """Whether the scene has its true orientation (a log may not): the ground errors and the
    bounds are computed at it."""
    return bool(np.isfinite(scene.position).all() and np.isfinite(scene.angles).all())


def ground_errors(res: Any) -> dict[str, np.ndarray]:
    """Per-pixel ground error maps of image II's halftone model per estimate of a run (every pixel
    for the recorded run, about 100 x 100 samples otherwise); none without the truth."""
    sc = res.scene
    if not truth_known(sc):
        return {}
    step = 1 if res.record else max(1, min(sc.k.width, sc.k.height) // 100)
    truth = (sc.position[1], sc.angles[1])
    return {name: halftone.ground_error(sc.dem, sc.k, truth, (e.position[1], e.angles[1]), step)
            for name, e in res.estimates.items()}


def ground_maps(ctx: MetricContext) -> dict[str, np.ndarray]:
    """:func:`ground_errors` of the run, made once."""
    return ctx.shared("ground_maps", lambda: ground_errors(ctx.result))


def ground_rmse(data: TerrainData, est: Estimate, ctx: MetricContext) -> Values:
    """The halftone model's horizontal error over every pixel of image II (RMS)."""
    maps = ground_maps(ctx)
    return Values([halftone.rmse(maps[ctx.name])]) if ctx.name in maps else None


def nees(data: TerrainData, est: Estimate) -> Values | None:
    """Image II's position NEES (3 dof), where the estimator gives a covariance."""
    cov = est.position_cov
    if cov is None or not np.all(np.isfinite(cov)) or np.linalg.det(cov) <= 0:
        return None
    return Values([float(em.nees(_position(data, est), cov))])


def prior_disagreement(data: TerrainData, est: Estimate, ctx: MetricContext) -> Values | None:
    """Image II's estimated orientation against the navigation system's measured one, normalised by
    the navigation prior's covariance less the estimate's, ``d' (P_nav - P)^-1 d`` (the pose, 6 dof,
    where the estimator gives ``pose_cov``; else the position, 3 dof): the estimate fuses the
    images with that prior, so with both consistent ``d`` has covariance ``P_nav - P`` (the same
    reading as a filter against its smoother, :func:`~workbench.estimation.consistency.disagreement`),
    and the figure's mean over runs is its dimension whatever the errors' distribution (its band is
    chi-square's: exact for Gaussian errors). The prior is :func:`.navigation.prior_covariance`
    mapped to image II (the common mode adds the velocity errors over the interval). Truth-free:
    the one verdict a log without the true orientation has. None for an estimate without a
    covariance, or one that claims no more than the prior (the navigation solution itself)."""
    from workbench.estimation import consistency
    from workbench.experiments.terrain import navigation

    cov = est.pose_cov if est.pose_cov is not None else est.position_cov
    if cov is None or not np.isfinite(cov).all():
        return None
    n = len(cov)
    M = navigation.error_map(ctx.cfg.mode, data.scene.interval)[1]
    prior = (M @ navigation.prior_covariance(ctx.cfg) @ M.T)[:n, :n]
    d = np.r_[est.position[1] - data.measured.position[1], wrap(est.angles[1] - data.measured.angles[1])][:n]
    v = consistency.disagreement(d[None], prior[None], np.zeros((1, n)), cov[None])
    return Values(v, dof=n) if np.isfinite(v).all() else None


def _extra(key: str):
    def fn(data: TerrainData, est: Estimate) -> Values | None:
        return Values([float(est.extras[key])]) if key in est.extras else None

    fn.__name__ = key
    return fn


def ba_bound(res: Any, cfg: TerrainConfig) -> dict[str, float]:
    """The bundle adjustment's own graph's Cramér-Rao variances of image II (its tie points and
    the DEM), where it ran."""
    from workbench.experiments.terrain import bounds

    est = res.estimates.get("gtsam-ba")
    if not truth_known(res.scene):  # (its graph is linearised at the true orientation)
        return {}
    return (bounds.bundle_adjustment(cfg, res.scene, est.extras) if est is not None else None) or {}


def cramer_rao(res: Any, cfg: TerrainConfig) -> dict[str, float]:
    """Image II's Cramér-Rao variances for this run (:mod:`.bounds`), from the search's problem
    (made here if no search estimator ran)."""
    from workbench.experiments.terrain import bounds
    from workbench.experiments.terrain.algorithms import search as rs

    problem = res.problem
    if problem is None:
        sc, meas = res.scene, res.measured
        problem = rs.make_problem(cfg, sc.k, sc.dem, meas.position, meas.angles, sc.images, sc.interval)
    P, r = bounds.state_bound(problem, res.state, cfg)
    return {**bounds.variances(P, cfg, res.scene.interval), "residual_variance": r}


def bound(ctx: MetricContext, est: Estimate) -> dict | None:
    """Image II's Cramér-Rao variances for this run (:mod:`.bounds`): the bundle adjustment's own
    graph's for ``gtsam-ba`` where it has one, else the images' and the navigation prior's; none
    without the truth (the bounds are at the true orientation)."""
    if not truth_known(ctx.result.scene):
        return None
    if ctx.name == "gtsam-ba":
        ba = ctx.shared("bound_ba", lambda: ba_bound(ctx.result, ctx.cfg))
        if ba:
            return ba
    return ctx.shared("bound", lambda: cramer_rao(ctx.result, ctx.cfg)) or None


def position_bound(data: TerrainData, est: Estimate, ctx: MetricContext) -> Values | None:
    b = bound(ctx, est)
    return None if b is None else Values([np.sqrt(b["position"])])


def attitude_bound(data: TerrainData, est: Estimate, ctx: MetricContext) -> Values | None:
    b = bound(ctx, est)
    return None if b is None else Values([1000.0 * np.sqrt(b["attitude"])])


def seconds(data: TerrainData, est: Estimate) -> Values:
    return Values([est.seconds])


METRICS: tuple[Metric, ...] = (
    Metric("position_error", position_error, "m", "image II's position error (3D norm), mean over runs",
           reduce="mean", across="mean", label="position error m"),
    Metric("attitude_error", attitude_error, "rad", "image II's attitude error (norm of the three angles), mean "
           "over runs", reduce="mean", across="mean", label="attitude error rad", fmt=".5f"),
    Metric("ground_rmse", ground_rmse, "m", "the halftone model's horizontal ground error over image II, RMS",
           label="ground rmse m"),
    *(Metric(f"rmse_{q}", _component(i), "m", f"image II's {q} error, RMS over runs") for i, q in enumerate("xyh")),
    *(Metric(f"d{q}", _component(i), "m", f"image II's {q} error (truth - estimate), mean over runs",
             reduce="mean", across="mean") for i, q in enumerate("xyh")),
    *(Metric(f"d{q}_fraction", _component(i, True), "of max", f"|d{q.upper()}| over the maximum linear error, "
             "mean over runs (the paper's Fig. 3)", reduce="mean", across="mean", label=f"d{q.upper()}/max",
             fmt=".3f") for i, q in enumerate("xy")),
    Metric("dr_fraction", dr_fraction, "of max", "sqrt(dX^2 + dY^2) over the maximum linear error, mean over runs "
           "(the paper's Fig. 3)", reduce="mean", across="mean", label="dR/max", fmt=".3f"),
    Metric("anees", nees, "", "image II's position NEES (3 dof), mean over runs", reduce="mean", dimension=3,
           label="ANEES"),
    Metric("prior_disagreement", prior_disagreement, "", "image II's estimate against the navigation system's "
           "measured orientation, normalised by the prior's covariance less the estimate's (6 dof with the pose's "
           "covariance, 3 with the position's; truth-free), mean over runs", reduce="mean", dimension=0,
           truth_free=True, label="vs prior"),
    Metric("kappa", _extra("kappa"), "", "the search's posterior: the node sum's variance inflation, mean over runs",
           reduce="mean", across="mean"),
    Metric("effective_nodes", _extra("effective_nodes"), "", "the search's posterior: its independent nodes, mean "
           "over runs", reduce="mean", across="mean", fmt=".0f"),
    Metric("position_bound", position_bound, "m", "image II's position Cramér-Rao bound (root of its mean variance)"),
    Metric("attitude_bound", attitude_bound, "mrad", "image II's attitude Cramér-Rao bound"),
    Metric("position_efficiency", None, "", "position error (RMS) over its bound",
           efficiency=("position_error", "position_bound")),
    Metric("attitude_efficiency", None, "", "attitude error (RMS) over its bound",
           efficiency=("attitude_error", "attitude_bound", 1000.0)),
    Metric("seconds", seconds, "s", "seconds a run, mean over runs", reduce="mean", label="s/run"),
)
"""Every terrain metric; the results table shows :data:`TABLE`."""

TABLE = ("position_error", "attitude_error", "ground_rmse", "dr_fraction", "dx_fraction", "anees", "seconds")
"""The results table's columns."""

CURVES: tuple[str, ...] = ()

BOUNDS = (("position", "m", "position_bound", "position_efficiency"),
          ("attitude", "mrad", "attitude_bound", "attitude_efficiency"))
"""The bounds table: quantity, unit, its bound's metric and its efficiency's."""

RENAMED: dict[str, str] = {
    **{f"rmse.{q}": f"rmse_{q}" for q in "xyh"},
    "paper.mean_x": "dx_fraction", "paper.std_x": "dx_fraction_std", "paper.mean_y": "dy_fraction",
    "paper.std_y": "dy_fraction_std", "paper.mean_r": "dr_fraction", "paper.std_r": "dr_fraction_std",
    "nees_band": "anees_band",
    **{f"bound.{q}": f"{q}_bound" for q in ("position", "attitude")},
    **{f"efficiency.{q}": f"{q}_efficiency" for q in ("position", "attitude")},
    **{f"efficiency_se.{q}": f"{q}_efficiency_se" for q in ("position", "attitude")},
    "/scene": "/scenario",
}
"""The metrics JSON's keys before the metric interface (old -> new), kept readable for one release."""
