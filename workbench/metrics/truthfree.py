"""The truth-free metrics every experiment has (:mod:`.metric`): what a filter's own innovations
say of it (:mod:`workbench.estimation.consistency`), for any estimate that reports them in its
``innovations`` field (a :class:`~workbench.estimation.consistency.Innovations`), built-in or a
researcher's own. None of them reads the truth: they judge an estimator on a real log.

* ``nis``: each used measurement's NIS, the mean over the measurements and runs, its chi-square
  band (the measurement's dimension);
* ``innovation_whiteness``: the share of lags 1..20 whose normalised autocorrelation of the
  whitened innovations is outside its 95 % band (about 0.05 for a consistent filter);
* ``nll``: the measurements' negative log-likelihood under the filter (the prediction-error
  decomposition), per run, the mean over runs; lower explains the data better; a measurement the
  filter left out (a gate) is charged as its least likely kept one
  (:meth:`~workbench.estimation.consistency.Innovations.charged_nll`), so leaving data out never wins;
* ``left_out``: the share of the measurements handed to the filter that it left out (a gate).

An experiment adds the disagreement of each causal estimator with the run's smoother
(:func:`reference`), where it can say what their states are.
"""

from __future__ import annotations

import numpy as np

from workbench.estimation import consistency
from workbench.metrics.base import Metric, Values

BELOW_MAX = 0.05
"""The share of steps a causal estimator's covariance may be below the smoother's (numerical ties at
the last steps, where both hold the same data) before its test fails."""
LAGS = 20
"""The lags of the whiteness test."""
WHITE_MAX = 0.15
"""The whiteness test passes with at most 3 of the 20 lags outside the band (for white innovations
each is outside with probability 0.05: 4 or more of 20 has probability 0.016)."""


def smoother(estimators: dict, estimates: dict, besides: str | None = None) -> str | None:
    """The run's smoother: the first estimator of the run (``estimators`` by name, those with an
    answer in ``estimates``) that uses the whole run and gives covariances, ``besides`` aside.
    Without truth it is the reference: each estimate's departure from it is what the recordings
    draw, and a causal estimator's disagreement with it a test."""
    return next((n for n, e in estimators.items() if n != besides and n in estimates and not e.causal
                 and e.covariances and e.delay == float("inf")), None)


def reference(ctx) -> str | None:
    """The run's smoother, which a causal estimator is compared with (:func:`~workbench.estimation.
    consistency.disagreement`): :func:`smoother`, itself aside; None for a smoother or an
    estimator without covariances."""
    me = ctx.estimator
    if me is None or not me.causal or not me.covariances:
        return None
    return smoother(ctx.estimators, ctx.estimates, ctx.name)


def _innovations(est) -> consistency.Innovations | None:
    innov = getattr(est, "innovations", None)
    return innov if isinstance(innov, consistency.Innovations) and innov.valid.any() else None


def nis(data, est) -> Values | None:
    innov = _innovations(est)
    return None if innov is None else Values(innov.nis(), innov.t, dof=innov.dimension)


def whiteness(data, est) -> Values | None:
    innov = _innovations(est)
    if innov is None or innov.valid.sum() < LAGS + 2:
        return None
    rho, band = consistency.whiteness(innov, LAGS)
    return Values([float(np.mean(np.abs(rho[np.isfinite(rho)]) > band))])


def nll(data, est) -> Values | None:
    innov = _innovations(est)
    return None if innov is None else Values(innov.charged_nll(), innov.t)


def left_out(data, est) -> Values | None:
    innov = _innovations(est)
    return None if innov is None else Values((~innov.used).astype(float), innov.t)


METRICS: tuple[Metric, ...] = (
    Metric("nis", nis, "", "the innovations' NIS, mean over the measurements and runs (truth-free)", reduce="mean",
           dimension=0, independent=True, truth_free=True, label="NIS"),
    Metric("innovation_whiteness", whiteness, "", f"share of lags 1..{LAGS} whose innovation autocorrelation is "
           "outside its 95 % band (0.05 if white; truth-free)", reduce="mean", across="mean", at_most=WHITE_MAX,
           truth_free=True, label="NIS lags out", fmt=".2f"),
    Metric("nll", nll, "", "the measurements' negative log-likelihood under the filter (one left out charged as "
           "its least likely kept one), a run's sum, mean over runs (truth-free)", reduce="sum", across="mean",
           truth_free=True, label="NLL", fmt=".1f"),
    Metric("left_out", left_out, "", "share of the measurements the filter left out (truth-free)", reduce="mean",
           truth_free=True, label="left out", fmt=".3f"),
)
