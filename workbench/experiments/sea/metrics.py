"""The sea experiment's metrics (:mod:`workbench.metrics.base`): each a function of a run's
dataset and one estimate, per step, errors ``truth - estimate`` in x, y (m), the azimuth alpha
and elevation beta (arcmin, alpha wrapped) and the range (m).

Table 2's figures are each run's RMSE, bias and largest error, their mean over the runs and its
spread (``across="mean"``); the position RMSE and the efficiencies pool every step of every run.
"""

from __future__ import annotations

import numpy as np

from workbench.estimation import consistency
from workbench.estimation import metrics as em
from workbench.estimation.angles import to_arcmin, wrap
from workbench.experiments.sea import bounds as sea_bounds
from workbench.experiments.sea import geometry
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData
from workbench.metrics import truthfree
from workbench.metrics.base import Metric, MetricContext, Values

QUANTITIES = ("x", "y", "alpha", "beta", "range")
UNITS = {"x": "m", "y": "m", "alpha": "arcmin", "beta": "arcmin", "range": "m", "position": "m"}
SHORT = {**UNITS, "alpha": "'", "beta": "'"}
SCALE = np.array([1.0, 1.0, to_arcmin(1.0), to_arcmin(1.0), 1.0])


def errors(data: SeaData, est: Estimate) -> np.ndarray:
    """Errors ``truth - estimate`` per step: x, y (m), alpha, beta (rad), range (m)."""
    return np.stack([
        data.target[:, 0] - est.position[:, 0],
        data.target[:, 1] - est.position[:, 1],
        wrap(data.alpha - est.alpha),
        data.beta - est.beta,
        data.range - est.range,
    ], axis=1)


def bounds(data: SeaData, cfg: SeaConfig) -> sea_bounds.Bounds | None:
    """The run's Cramér-Rao bounds (:class:`.bounds.Bounds`, which keeps each delay's once made);
    none where the angles come from images (their noise is the image stage's, not the model's)."""
    if cfg.from_images or not np.isfinite(data.target).all():
        return None  # (the bound is at the truth: a log without it, or with a partial one, has none)
    truth = sea_bounds.Truth(data.target, data.observer, data.seen, data.disturbed)
    model = sea_bounds.Model(data.dt, data.height, data.sigma_acc, data.sigma_alpha, data.sigma_beta,
                             data.sigma_observer, cfg.prior_speed,
                             float(np.deg2rad(cfg.impulse_sigma_deg)) if cfg.scenario == "impulse" else 0.0)
    return sea_bounds.Bounds(model, [truth])


def _errors(data: SeaData, est: Estimate, ctx: MetricContext) -> np.ndarray:
    """``(T, 5)``: x, y (m), alpha, beta (arcmin), range (m)."""
    return ctx.shared(("errors", ctx.name), lambda: errors(data, est) * SCALE)


def position_error(data: SeaData, est: Estimate, ctx: MetricContext) -> Values:
    e = _errors(data, est, ctx)
    return Values(np.hypot(e[:, 0], e[:, 1]), data.t)


def _quantity(i: int, signed: bool):
    def fn(data: SeaData, est: Estimate, ctx: MetricContext) -> Values:
        e = _errors(data, est, ctx)[:, i]
        return Values(e if signed else np.abs(e), data.t)

    fn.__name__ = f"{'error' if signed else 'abs_error'}_{QUANTITIES[i]}"
    return fn


def nees(data: SeaData, est: Estimate) -> Values | None:
    """The NEES of (x, y, vx, vy) at each step, where the estimator gives that state's covariance."""
    if est.state_cov is None:
        return None
    e = data.target - np.concatenate([est.position, est.velocity], axis=1)
    ok = np.all(np.isfinite(e), axis=1)
    n = np.full(data.steps, np.nan)
    n[ok] = em.nees(e[ok], est.state_cov[ok])
    return Values(n, data.t)


def disagreement(data: SeaData, est: Estimate, ctx: MetricContext) -> Values | None:
    """A causal estimator's position against the run's smoother's (:func:`.truthfree.reference`)
    at each step, normalised by the difference of their covariances (2 dof; truth-free)."""
    ref = truthfree.reference(ctx)
    if ref is None or est.covariance is None or ctx.estimates[ref].covariance is None:
        return None
    s = ctx.estimates[ref]
    return Values(consistency.disagreement(est.position, est.covariance, s.position, s.covariance), data.t)


def smoother_gap(data: SeaData, est: Estimate, ctx: MetricContext) -> Values | None:
    """A causal estimator's position against the run's smoother's at each step, normalised by the
    sum of their covariances (2 dof; truth-free): beyond chi-square's 99.9 % point over most of the
    run, the two are in different basins (:mod:`workbench.metrics.diagnosis`)."""
    ref = truthfree.reference(ctx)
    if ref is None or est.covariance is None or ctx.estimates[ref].covariance is None:
        return None
    s = ctx.estimates[ref]
    return Values(consistency.disagreement(est.position, est.covariance, s.position, -s.covariance), data.t)


def residual(data: SeaData, est: Estimate, ctx: MetricContext | None = None) -> Values | None:
    """Each step's measured angles against those the estimate's position predicts from the
    measured camera, ``r = (alpha~ - h_alpha, beta~ - h_beta)``, normalised by the measurement's
    noise with that fix's folded in (:func:`.geometry.effective_noise`) less the estimate's own
    share, ``r' (R - J P J')^-1 r``
    (:func:`~workbench.estimation.consistency.residual`): chi-square with 2 degrees of freedom for
    a consistent estimator that gives its covariance, a test of any estimate, a filter or a
    smoother, built-in or a researcher's, with no innovations of its own to show (truth-free).
    It holds for one that keeps the camera as an offset (:mod:`.observer`) too: the fix's error
    less the offset's, ``sigma_o^2 (1 - 1/n)`` per axis, is what ``R - J P J'`` leaves when P
    holds the offset's ``sigma_o^2 / n``. Without a covariance, ``r' R^-1 r``: a figure to
    compare, no test (the geometric inverse fits every measurement exactly: 0). The noise is the one
    the estimators were told (``--assume-sigma-*``, :meth:`.contract.Experiment.assumed`): a test
    without truth knows no other."""
    if est.position is None or not np.isfinite(est.position).any():
        return None
    if ctx is not None and ctx.cfg is not None:
        from workbench.experiments.sea import run as sea_run

        data = ctx.shared("assumed", lambda: sea_run.assumed(data, ctx.cfg))
    alpha, beta = geometry.angles(est.position, data.observer_meas, data.course, data.height)
    r = np.stack([wrap(data.alpha_meas - alpha), data.beta_meas - beta], axis=-1)
    J = geometry.angle_jacobian(est.position, data.observer_meas, data.height)
    R = geometry.effective_noise(est.position, data.observer_meas, data.height, data.sigma_alpha, data.sigma_beta,
                                 data.sigma_observer, J)
    HPH = None if est.covariance is None else J @ est.covariance @ np.swapaxes(J, -1, -2)
    return Values(consistency.residual(r, R, HPH), data.t, dof=None if HPH is None else 2)


def below_smoother(data: SeaData, est: Estimate, ctx: MetricContext) -> Values | None:
    """1 at each step where a causal estimator's position covariance is below the smoother's in
    some direction (:func:`~workbench.estimation.consistency.below`; truth-free)."""
    ref = truthfree.reference(ctx)
    if ref is None or est.covariance is None or ctx.estimates[ref].covariance is None:
        return None
    return Values(consistency.below(est.covariance, ctx.estimates[ref].covariance), data.t)


def coverage(data: SeaData, est: Estimate) -> Values:
    return Values(np.isfinite(est.position[:, 0]).astype(float), data.t)


def _bound(q: str):
    """The Cramér-Rao bound of quantity ``q`` for the estimator's delay (m, arcmin for the angles) where
    its error is finite; none where the angles come from images (their noise is the image stage's)."""

    def fn(data: SeaData, est: Estimate, ctx: MetricContext) -> Values | None:
        b = ctx.shared("bounds", lambda: bounds(data, ctx.cfg))
        if b is None:
            return None
        delay = ctx.estimator.delay if ctx.estimator is not None else 0.0
        e = _errors(data, est, ctx)
        err = np.hypot(e[:, 0], e[:, 1]) if q == "position" else e[:, QUANTITIES.index(q)]
        v = b.variances(delay)[q][0]
        ok = np.isfinite(err) & np.isfinite(v)
        if not ok.any():
            return None
        scale = to_arcmin(1.0) if q in ("alpha", "beta") else 1.0
        return Values(np.where(ok, np.sqrt(np.where(ok, v, 0.0)) * scale, np.nan), data.t)

    fn.__name__ = f"{q}_bound"
    return fn


def seconds(data: SeaData, est: Estimate) -> Values:
    return Values([est.seconds])


METRICS: tuple[Metric, ...] = (
    Metric("position_rmse", position_error, "m", "position error, RMS over every step of every run",
           label="pos rmse m"),
    *(Metric(f"rmse_{q}", _quantity(i, False), UNITS[q], f"each run's RMS error of {q}, mean over runs",
             across="mean", label=f"rmse {q} {SHORT[q]}", fmt=".3g") for i, q in enumerate(QUANTITIES)),
    *(Metric(f"bias_{q}", _quantity(i, True), UNITS[q], f"each run's mean error of {q}, mean over runs",
             reduce="mean", across="mean", label=f"bias {q} {SHORT[q]}", fmt=".3g") for i, q in enumerate(QUANTITIES)),
    *(Metric(f"max_{q}", _quantity(i, False), UNITS[q], f"each run's largest error of {q}, mean over runs",
             reduce="max", across="mean", label=f"max {q} {SHORT[q]}") for i, q in enumerate(QUANTITIES)),
    Metric("anees", nees, "", "the NEES of (x, y, vx, vy), mean over the steps and runs", reduce="mean",
           dimension=4, label="ANEES"),
    Metric("disagreement", disagreement, "", "a causal estimator's position against the run's smoother's, "
           "normalised by the difference of their covariances (2 dof; truth-free), mean", reduce="mean", dimension=2,
           truth_free=True, label="vs smoother"),
    Metric("smoother_gap", smoother_gap, "", "a causal estimator's position against the run's smoother's, "
           "normalised by the sum of their covariances (2 dof; truth-free), median: over 13.8, the 99.9 % point, in "
           "another basin", reduce="median", truth_free=True, label="gap"),
    Metric("angle_residual", residual, "", "each step's measured angles against the estimate's, normalised by their "
           "noise less the estimate's own covariance (chi-square, 2 dof, where it gives one; truth-free), mean",
           reduce="mean", dimension=0, truth_free=True, label="residual", evidence=True),
    Metric("below_smoother", below_smoother, "", "share of the steps where a causal estimator's covariance is "
           "below the smoother's in some direction (it claims a certainty the data do not give; truth-free)",
           reduce="mean", at_most=truthfree.BELOW_MAX, truth_free=True, window=False),
    Metric("coverage", coverage, "", "share of the steps with an estimate", reduce="mean"),
    *(Metric(f"{q}_bound", _bound(q), UNITS[q], f"{q}'s Cramér-Rao bound (root of its mean variance)")
      for q in ("x", "y", "position", "range", "alpha", "beta")),
    *(Metric(f"{q}_efficiency", None, "", f"{q}'s RMSE over its bound",
             efficiency=("position_rmse" if q == "position" else f"rmse_{q}", f"{q}_bound"))
      for q in ("x", "y", "position", "range", "alpha", "beta")),
    Metric("seconds", seconds, "s", "seconds a run, mean over runs", reduce="mean", label="s/run", fmt=".3f"),
)
"""Every sea metric; the results table shows :data:`TABLE` (each with its spread over runs)."""

BOOTSTRAP_NEES = "anees"
"""The NEES the parametric bootstrap reads on each resample (:mod:`workbench.metrics.bootstrap`)."""

NOISE_GROUPS = {"state": "acceleration", "measurement": "angles", "motion": "acceleration", "angle": "angles"}
"""What the diagnosis (:mod:`workbench.metrics.diagnosis`) calls the noise groups: a filter's
state uncertainty is the target's acceleration noise, its measurement noise the angles'."""

TABLE = ("rmse_x", "rmse_y", "rmse_alpha", "rmse_beta", "bias_x", "bias_y", "bias_alpha", "bias_beta", "seconds")
"""The results table's columns: Table 2's."""

CURVES: tuple[str, ...] = ()
"""Built-in metrics the recording's "metrics" tab draws over runs (beside every plugin's)."""

BOUNDS = tuple((q, "'" if q in ("alpha", "beta") else "m", f"{q}_bound", f"{q}_efficiency")
               for q in ("position", "range", "alpha", "beta"))
"""The bounds table: quantity, unit, its bound's metric and its efficiency's."""

RENAMED: dict[str, str] = {
    **{f"{group}.{q}": f"{group}_{q}" for group in ("rmse", "bias", "max") for q in QUANTITIES},
    **{f"{group}_std.{q}": f"{group}_{q}_std" for group in ("rmse", "bias") for q in QUANTITIES},
    **{f"bound.{q}": f"{q}_bound" for q in ("x", "y", "position", "range", "alpha", "beta")},
    **{f"efficiency.{q}": f"{q}_efficiency" for q in ("x", "y", "position", "range", "alpha", "beta")},
    **{f"efficiency_se.{q}": f"{q}_efficiency_se" for q in ("x", "y", "position", "range", "alpha", "beta")},
    "nees_inside_band": "anees_inside_band",
}
"""The metrics JSON's keys before the metric interface (old -> new), kept readable for one release."""
