"""The omni experiment's metrics (:mod:`workbench.metrics.base`): each a function of a run's
dataset and one estimate, scored on the dataset's grid (the graph's keyframes, where every
estimator has a pose), errors ``truth - estimate`` with the heading wrapped; the figures count
the steps from ``settle`` seconds on (the paper's claims are for the settled filter), and each
time series also gives its figure over the whole run (``<metric>_whole_run``).
"""

from __future__ import annotations

import math

import numpy as np

from workbench.estimation import consistency
from workbench.estimation.alignment import umeyama
from workbench.estimation.angles import wrap
from workbench.experiments.omni import evaluate
from workbench.experiments.omni.config import BATCH_STARTS
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData
from workbench.metrics import truthfree
from workbench.metrics.base import Metric, MetricContext, Values


def _pose(data: OmniData, est: SlamEstimate, ctx: MetricContext, name: str | None = None
          ) -> tuple[np.ndarray, np.ndarray]:
    """An estimate's pose and covariance on the grid, made once a run (``name``: whose, default the
    metric's own estimator; the smoother's, for the metrics that compare with it)."""
    return ctx.shared(("pose", name or ctx.name), lambda: evaluate.on_grid(est, data.grid))


def _errors(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> np.ndarray:
    return ctx.shared(("errors", ctx.name),
                      lambda: evaluate.pose_errors(data.truth[data.grid], _pose(data, est, ctx)[0]))


def _t(data: OmniData) -> np.ndarray:
    return data.t[data.grid]


def position_error(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    e = _errors(data, est, ctx)
    return Values(np.hypot(e[:, 0], e[:, 1]), _t(data))


def heading_error(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    return Values(np.degrees(np.abs(_errors(data, est, ctx)[:, 2])), _t(data))


def final_position(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    e = _errors(data, est, ctx)[-1]
    return Values([np.hypot(e[0], e[1])])


def _map_errors(data: OmniData, est: SlamEstimate) -> np.ndarray:
    m = est.final_map - data.landmarks
    return np.hypot(m[:, 0], m[:, 1])


def map_error(data: OmniData, est: SlamEstimate) -> Values:
    """Each landmark's error in the final map (m; NaN where not initialised)."""
    return Values(_map_errors(data, est))


def aligned_map_error(data: OmniData, est: SlamEstimate) -> Values | None:
    """Each landmark's error in the final map after the best rigid alignment of the map to the
    known one (as ``evo_ape -a`` aligns; m): what a log without the robot's truth but with a
    landmark survey can score. None with fewer than three landmarks on both sides."""
    ok = np.isfinite(est.final_map).all(axis=1) & np.isfinite(data.landmarks).all(axis=1)
    if ok.sum() < 3:
        return None
    a = umeyama(est.final_map[ok], data.landmarks[ok])
    moved = a.apply(np.column_stack([est.final_map, np.zeros(len(est.final_map))]))[:, :2]
    return Values(np.hypot(*(moved - data.landmarks).T))


def landmarks(data: OmniData, est: SlamEstimate) -> Values:
    """1 for each landmark in the final map, surveyed or not (a log without a survey maps them too)."""
    return Values(np.isfinite(est.final_map).all(axis=1).astype(float))


def unmapped(data: OmniData, est: SlamEstimate) -> Values | None:
    """1 for each bearing of a landmark the final map does not hold (never initialised, or taken
    out), 0 for the others: the data an estimator with a map could not use (truth-free). None
    without a map."""
    lm = est.final_map
    if est.map_steps is None or not len(est.map_steps) or len(data.meas_lm) == 0:
        return None
    return Values((~np.isfinite(lm[data.meas_lm]).all(axis=1)).astype(float), data.t[data.meas_step])


def init_delay(data: OmniData, est: SlamEstimate) -> Values:
    """Seconds from each landmark's first sighting to its initialisation (NaN: never)."""
    d = np.full(len(data.landmarks), np.nan)
    ok = est.init_step >= 0
    d[ok] = data.t[est.init_step[ok]] - data.t[est.first_seen[ok]]
    return Values(d)


def _sigmas(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> np.ndarray:
    cov = _pose(data, est, ctx)[1]
    return np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))


def sigma_position(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    s = _sigmas(data, est, ctx)
    return Values(np.hypot(s[:, 0], s[:, 1]), _t(data))


def sigma_x(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    return Values(_sigmas(data, est, ctx)[:, 0], _t(data))


def sigma_y(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    return Values(_sigmas(data, est, ctx)[:, 1], _t(data))


def sigma_heading(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    return Values(np.degrees(_sigmas(data, est, ctx)[:, 2]), _t(data))


def nees(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    """The pose's NEES (3 dof) at each grid step."""
    return Values(evaluate.pose_nees(_errors(data, est, ctx), _pose(data, est, ctx)[1]), _t(data))


RESIDUAL_CAP = 6.635
"""Each bearing's squared normalised residual is truncated here (chi-square, 1 dof, 99 %): a misread
or a misassociation counts as much as the worst bearing kept, not as a thousand good ones."""


def bearing_residual(data: OmniData, est: SlamEstimate) -> Values | None:
    """Each bearing against the estimate: the bearing its pose at that step (a smoother's whole
    trajectory as held at the end, where it gives one) and its final map predict, the residual over
    the bearing's sigma, squared and truncated at :data:`RESIDUAL_CAP` (truncated least squares,
    Yang et al. 2020), per bearing; its RMS is near 1 for an estimate that explains the bearings as
    their noise says, far above for one in a wrong place (truth-free). A figure to compare the
    estimators by, any of them with a map, a plugin too; not a chi-square test (the estimate's own
    covariance of pose and map jointly is not in it). None without a map."""
    lm = est.final_map
    if est.pose is None or lm is None or not np.isfinite(lm).any() or len(data.meas_step) == 0:
        return None
    smoothed = est.smoothed is not None and len(est.smoothed) == len(est.steps)
    p = evaluate.smoothed_on_grid(est, data.meas_step) if smoothed else evaluate.on_grid(est, data.meas_step)[0]
    m = lm[data.meas_lm] if len(lm) else np.full((len(data.meas_step), 2), np.nan)
    predicted = np.arctan2(m[:, 1] - p[:, 1], m[:, 0] - p[:, 0]) - p[:, 2]
    r2 = (wrap(data.meas_bearing - predicted) / data.bearing_sigma()) ** 2
    return Values(np.sqrt(np.minimum(r2, RESIDUAL_CAP)), data.t[data.meas_step])


def fix_nees(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    """The position's NEES (2 dof) at each grid step where the truth is a position fix: a log's
    ``truth.csv`` with a ``sigma_m`` (a GPS track's noise) or without headings. The fix's own noise
    is added to the estimate's covariance, ``e' (P_xy + sigma^2 I)^-1 e``: the error against a
    noisy fix is the estimate's error plus the fix's, independent of it, so a consistent estimator
    is chi-square with 2 degrees of freedom against it too. None where the truth is a whole pose
    known exactly (the pose NEES, ``anees``, holds)."""
    sigma = data.truth_sigma
    truth = data.truth[data.grid]
    if not np.isfinite(truth[:, :2]).any() or (sigma is None and not np.isnan(truth[:, 2]).all()):
        return None
    e = _errors(data, est, ctx)[:, :2]
    cov = _pose(data, est, ctx)[1][:, :2, :2].copy()
    if sigma is not None:
        cov += np.nan_to_num(np.asarray(sigma, float)[data.grid])[:, None, None] ** 2 * np.eye(2)
    return Values(evaluate.pose_nees(e, cov), _t(data))


def disagreement(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    """A causal estimator's pose against the run's smoother's (:func:`.truthfree.reference`) at
    each grid step, normalised by the difference of their covariances (3 dof; truth-free)."""
    ref = truthfree.reference(ctx)
    if ref is None:
        return None
    pose, cov = _pose(data, est, ctx)
    spose, scov = _pose(data, ctx.estimates[ref], ctx, ref)
    return Values(consistency.disagreement(pose, cov, spose, scov, angles=(2,)), _t(data))


def smoother_gap(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    """A causal estimator's pose against the run's smoother's at each grid step, normalised by the
    sum of their covariances (3 dof; truth-free): no larger than :func:`disagreement` where both are
    consistent, and defined where the filter claims less than the smoother. Beyond chi-square's
    99.9 % point over most of the run, the two are in different basins
    (:mod:`workbench.metrics.diagnosis`)."""
    ref = truthfree.reference(ctx)
    if ref is None:
        return None
    pose, cov = _pose(data, est, ctx)
    spose, scov = _pose(data, ctx.estimates[ref], ctx, ref)
    return Values(consistency.disagreement(pose, cov, spose, -scov, angles=(2,)), _t(data))


def below_smoother(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    """1 at each grid step where a causal estimator's pose covariance is below the smoother's in
    some direction (:func:`~workbench.estimation.consistency.below`; truth-free)."""
    ref = truthfree.reference(ctx)
    if ref is None:
        return None
    scov = _pose(data, ctx.estimates[ref], ctx, ref)[1]
    return Values(consistency.below(_pose(data, est, ctx)[1], scov), _t(data))


def coverage(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    e = _errors(data, est, ctx)
    return Values(np.isfinite(np.hypot(e[:, 0], e[:, 1])).astype(float), _t(data))


def failures(data: OmniData, est: SlamEstimate) -> Values:
    return Values([est.failures])


def gated(data: OmniData, est: SlamEstimate) -> Values:
    return Values([est.gated])


def _started(where: str):
    def started(data: OmniData, est: SlamEstimate) -> Values | None:
        """1 if the estimator started from ``where`` (it chose by its cost on the data)."""
        return Values([float(est.start == where)]) if est.start else None

    started.__name__ = f"started_{where}"
    return started


def fit(data: OmniData, est: SlamEstimate) -> Values | None:
    """A least-squares smoother's residual chi-square at its answer (:func:`.graph.fit`)."""
    return None if est.fit is None else Values([est.fit[0]], dof=est.fit[1])


def start_cost(data: OmniData, est: SlamEstimate) -> Values | None:
    """The winning start's cost on the data (:func:`.graph.robust_cost`)."""
    return Values([est.start_costs[est.start]]) if est.start else None


def _aligned(data: OmniData, est: SlamEstimate, ctx: MetricContext):
    def make():
        truth, pose = data.truth[data.grid], _pose(data, est, ctx)[0]
        a = umeyama(pose[:, :2], truth[:, :2])
        return evaluate.pose_errors(truth, a.apply(pose)), a

    return ctx.shared(("aligned", ctx.name), make)


def aligned_position(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    e = _aligned(data, est, ctx)[0]
    return Values(np.hypot(e[:, 0], e[:, 1]), _t(data))


def aligned_heading(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values:
    return Values(np.degrees(np.abs(_aligned(data, est, ctx)[0][:, 2])), _t(data))


def _truth_known(data: OmniData) -> bool:
    return bool(np.isfinite(data.truth[data.grid]).all(axis=1).sum() >= 2)


def alignment_rotation(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    return Values([np.degrees(_aligned(data, est, ctx)[1].rotation)]) if _truth_known(data) else None


def alignment_translation(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    return Values([np.hypot(*_aligned(data, est, ctx)[1].translation)]) if _truth_known(data) else None


def _smoothed(data: OmniData, est: SlamEstimate) -> np.ndarray | None:
    if est.smoothed is None:
        return None
    return evaluate.pose_errors(data.truth[data.grid], evaluate.smoothed_on_grid(est, data.grid))


def smoothed_position(data: OmniData, est: SlamEstimate) -> Values | None:
    """A smoother's whole trajectory as it holds it at the end (iSAM2's), against the truth."""
    e = _smoothed(data, est)
    return None if e is None else Values(np.hypot(e[:, 0], e[:, 1]), _t(data))


def smoothed_heading(data: OmniData, est: SlamEstimate) -> Values | None:
    e = _smoothed(data, est)
    return None if e is None else Values(np.degrees(np.abs(e[:, 2])), _t(data))


def _bound(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> dict | None:
    """The run's Cramér-Rao variances for this estimator's delay (filtering for a causal one,
    smoothing otherwise), or None (bearings from images carry the image stage's noise, not the model's)."""
    crb = ctx.shared("bounds", lambda: evaluate.bounds(data, ctx.cfg, ctx.products.get("keyframes")))
    if not crb:
        return None
    delay = ctx.estimator.delay if ctx.estimator is not None else 0.0
    return {**crb[0.0 if delay == 0 else math.inf], "map": crb["map"]}


def position_bound(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    b, e = _bound(data, est, ctx), position_error(data, est, ctx)
    if b is None or not np.isfinite(e.values).any():
        return None
    return Values(np.where(np.isfinite(e.values), np.sqrt(b["position"]), np.nan), e.t)


def heading_bound(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    b, e = _bound(data, est, ctx), heading_error(data, est, ctx)
    if b is None or not np.isfinite(e.values).any():
        return None
    return Values(np.where(np.isfinite(e.values), np.degrees(np.sqrt(b["heading"])), np.nan), e.t)


def map_bound(data: OmniData, est: SlamEstimate, ctx: MetricContext) -> Values | None:
    b, m = _bound(data, est, ctx), _map_errors(data, est)
    ok = np.isfinite(m) & np.isfinite(b["map"]) if b is not None else None
    if ok is None or not ok.any():
        return None
    return Values(np.where(ok, np.sqrt(b["map"]), np.nan))


def seconds(data: OmniData, est: SlamEstimate) -> Values:
    return Values([est.seconds])


METRICS: tuple[Metric, ...] = (
    Metric("position_rmse", position_error, "m", "position error, RMS over the steps and runs", label="pos rmse m"),
    Metric("position_max", position_error, "m", "largest position error", reduce="max", label="pos max m"),
    Metric("heading_rmse", heading_error, "deg", "heading error, RMS", label="head rmse deg"),
    Metric("heading_max", heading_error, "deg", "largest heading error", reduce="max", label="head max deg"),
    Metric("map_rmse", map_error, "m", "the final map's landmark errors, RMS", label="map rmse m"),
    Metric("aligned_map_rmse", aligned_map_error, "m", "the final map's landmark errors after its best rigid "
           "alignment to the known map, RMS (needs no robot truth)", label="map aligned m"),
    Metric("final_position", final_position, "m", "the last pose's position error, RMS over runs", label="final m"),
    Metric("sigma_position_max", sigma_position, "m", "largest own position sigma (its x, y in quadrature)",
           reduce="max", label="sigma pos max m"),
    Metric("sigma_x_max", sigma_x, "m", "largest own sigma of x", reduce="max"),
    Metric("sigma_y_max", sigma_y, "m", "largest own sigma of y", reduce="max"),
    Metric("sigma_heading_max", sigma_heading, "deg", "largest own heading sigma", reduce="max",
           label="sigma head max deg"),
    Metric("bearing_residual", bearing_residual, "sigma", "each bearing's residual against the estimate's pose "
           "and final map over its sigma, truncated at the 99 % gate, RMS (1: explained as the noise says; "
           "truth-free)", truth_free=True, label="bearing res", fmt=".2f"),
    Metric("fix_nees", fix_nees, "", "the position's NEES against a position fix (a GPS track), its noise added to "
           "the estimate's covariance (2 dof), mean over the fixes and runs", reduce="mean", dimension=2,
           label="fix NEES"),
    Metric("anees", nees, "", "the pose's NEES (3 dof), mean over the steps and runs", reduce="mean", dimension=3,
           label="ANEES"),
    Metric("disagreement", disagreement, "", "a causal estimator's pose against the run's smoother's, normalised "
           "by the difference of their covariances (3 dof; truth-free), mean", reduce="mean", dimension=3,
           truth_free=True, label="vs smoother"),
    Metric("smoother_gap", smoother_gap, "", "a causal estimator's pose against the run's smoother's, normalised by "
           "the sum of their covariances (3 dof; truth-free), median: over 16.3, the 99.9 % point, in another "
           "basin", reduce="median", truth_free=True, label="gap"),
    Metric("below_smoother", below_smoother, "", "share of the grid steps where a causal estimator's covariance is "
           "below the smoother's in some direction (it claims a certainty the data do not give; truth-free)",
           reduce="mean", at_most=truthfree.BELOW_MAX, truth_free=True, window=False),
    Metric("landmarks", landmarks, "", "landmarks in the final map, mean over runs", reduce="sum", across="mean",
           fmt=".1f"),
    Metric("unmapped", unmapped, "", "share of the bearings whose landmark the final map does not hold (never "
           "initialised or taken out: data the estimator could not use; truth-free)", reduce="mean",
           truth_free=True, window=False, fmt=".3f"),
    Metric("init_seconds_mean", init_delay, "s", "mean delay from a landmark's first sighting to its initialisation",
           reduce="mean"),
    Metric("init_seconds_median", init_delay, "s", "median initialisation delay", reduce="median", label="init s",
           fmt=".1f"),
    Metric("init_seconds_max", init_delay, "s", "longest initialisation delay", reduce="max"),
    Metric("coverage", coverage, "", "share of the grid's steps with an estimate", reduce="mean", window=False),
    Metric("failures", failures, "", "rejected updates, summed over runs", reduce="sum", across="sum", fmt=".0f"),
    Metric("bearings_gated", gated, "", "bearings a gate left out (misreads, outliers), summed over runs",
           reduce="sum", across="sum", fmt=".0f"),
    *(Metric(f"started_{where}", _started(where), "", f"runs that started from {where} (the lowest cost on the "
             "data among the starts tried)", reduce="sum", across="sum", truth_free=True, fmt=".0f")
      for where in BATCH_STARTS),
    Metric("fit", fit, "", "a least-squares smoother's weighted squared residuals at its answer (odometry and the "
           "bearings it kept), chi-square with the residuals less the unknowns; mean over runs (truth-free)",
           reduce="mean", dimension=0, truth_free=True, label="fit chi2", fmt=".0f"),
    Metric("start_cost", start_cost, "", "the winning start's robust cost on the data (truncated least squares), "
           "mean over runs", reduce="mean", across="mean", truth_free=True),
    Metric("aligned_position_rmse", aligned_position, "m", "position error after the best rigid alignment "
           "(evo_ape -a), RMS"),
    Metric("aligned_heading_rmse", aligned_heading, "deg", "heading error after the best rigid alignment, RMS"),
    Metric("alignment_rotation", alignment_rotation, "deg", "the best alignment's rotation, RMS over runs"),
    Metric("alignment_translation", alignment_translation, "m", "the best alignment's translation, RMS over runs"),
    Metric("smoothed_position_rmse", smoothed_position, "m", "a smoother's whole trajectory as held at the end, "
           "position RMS"),
    Metric("smoothed_heading_rmse", smoothed_heading, "deg", "a smoother's whole trajectory as held at the end, "
           "heading RMS"),
    Metric("position_bound", position_bound, "m", "the position's Cramér-Rao bound (root of its mean variance)"),
    Metric("heading_bound", heading_bound, "deg", "the heading's Cramér-Rao bound"),
    Metric("map_bound", map_bound, "m", "the map's Cramér-Rao bound"),
    Metric("position_efficiency", None, "", "position RMSE over its bound",
           efficiency=("position_rmse", "position_bound")),
    Metric("heading_efficiency", None, "", "heading RMSE over its bound", efficiency=("heading_rmse", "heading_bound")),
    Metric("map_efficiency", None, "", "map RMSE over its bound", efficiency=("map_rmse", "map_bound")),
    Metric("seconds", seconds, "s", "seconds a run, mean over runs", reduce="mean", label="s/run"),
)
"""Every omni metric; the results table shows :data:`TABLE`."""

BOOTSTRAP_NEES = "anees"
"""The NEES the parametric bootstrap reads on each resample (:mod:`workbench.metrics.bootstrap`)."""

NOISE_GROUPS = {"state": "odometry", "measurement": "bearings", "odometry": "odometry", "bearing": "bearings"}
"""What the diagnosis (:mod:`workbench.metrics.diagnosis`) calls the noise groups: a filter's
state uncertainty is the odometry's (the motion noise), its measurement noise the bearings'; a
graph's residual groups by their factors."""

TABLE = ("position_rmse", "position_max", "heading_rmse", "heading_max", "map_rmse", "aligned_map_rmse",
         "sigma_position_max",
         "sigma_heading_max", "anees", "landmarks", "init_seconds_median", "seconds")
"""The results table's columns."""

CURVES: tuple[str, ...] = ("fix_nees",)
"""Built-in metrics the recording's "metrics" tab draws over runs (beside every plugin's)."""

BOUNDS = (("position", "m", "position_bound", "position_efficiency"), ("heading", "deg", "heading_bound",
                                                                     "heading_efficiency"),
          ("map", "m", "map_bound", "map_efficiency"))
"""The bounds table: quantity, unit, its bound's metric and its efficiency's."""

_NESTED = {"rmse": {"position": "position_rmse", "heading": "heading_rmse", "map": "map_rmse"},
           "rmse_whole_run": {"position": "position_rmse_whole_run", "heading": "heading_rmse_whole_run"},
           "max": {"position": "position_max", "heading": "heading_max"},
           "max_whole_run": {"position": "position_max_whole_run", "heading": "heading_max_whole_run"},
           "final": {"position": "final_position"},
           "sigma": {"position_max": "sigma_position_max", "x_max": "sigma_x_max", "y_max": "sigma_y_max",
                     "heading_max": "sigma_heading_max"},
           "init_seconds": {"mean": "init_seconds_mean", "median": "init_seconds_median", "max": "init_seconds_max"},
           "rmse_aligned": {"position": "aligned_position_rmse", "heading": "aligned_heading_rmse"},
           "rmse_aligned_whole_run": {"position": "aligned_position_rmse_whole_run",
                                      "heading": "aligned_heading_rmse_whole_run"},
           "alignment": {"rotation_deg": "alignment_rotation", "translation": "alignment_translation"},
           "rmse_smoothed": {"position": "smoothed_position_rmse", "heading": "smoothed_heading_rmse"},
           "rmse_smoothed_whole_run": {"position": "smoothed_position_rmse_whole_run",
                                       "heading": "smoothed_heading_rmse_whole_run"},
           "bound": {"position": "position_bound", "heading": "heading_bound", "map": "map_bound"},
           "efficiency": {"position": "position_efficiency", "heading": "heading_efficiency",
                          "map": "map_efficiency"},
           "efficiency_se": {"position": "position_efficiency_se", "heading": "heading_efficiency_se"}}
RENAMED: dict[str, str] = {
    **{f"{group}.{key}": new for group, keys in _NESTED.items() for key, new in keys.items()},
    "nees_inside_band": "anees_inside_band", "landmarks_initialised": "landmarks",
    "/nees_band": "/metric_table.anees.band",
}
"""The metrics JSON's keys before the metric interface (old -> new), kept readable for one release."""
