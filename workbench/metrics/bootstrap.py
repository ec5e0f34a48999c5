"""A truth-free NEES: the parametric bootstrap of a run's own answer (Efron and Tibshirani, *An
Introduction to the Bootstrap*, 1993, ch. 6; used to check an estimator's covariance where no
truth is known, e.g. Barfoot, *State Estimation for Robotics*, sec. 5.1 on the bias and
consistency of a nonlinear batch estimate).

With ``--bootstrap B``, each run simulates ``B`` datasets from its own answer, by the experiment's
``resample.resample(result, cfg, rng)`` (its package's ``resample`` role: omni's and sea's): the
run's smoother's trajectory and map taken as the truth, the measurements' schedule kept, and their
noise the one the data identify (the smoother's variance components, :mod:`.diagnosis`). Every
estimator of the run then runs on each as it ran on the data (the config's assumptions, its
gates), and its NEES against that truth, the experiment's own NEES metric
(``metrics.BOOTSTRAP_NEES``), is its ``bootstrap_nees``: one figure per resample, the mean over
its scored steps, so the band counts the resamples (the errors of one run are correlated over its
steps, as the truth's NEES band counts runs).

What it sees that the residuals cannot: a linearised covariance smaller than the error where the
geometry bends the problem (a noise that fits the data, and a NEES over its band all the same), and
whether a noise assumed too wide or narrow still leaves the covariance covering the error. What it
cannot see: a fault the resampling does not put in (outliers, a misread id, a wrong motion model),
and a smoother's answer far from the truth (it simulates round the answer it is given).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from workbench.errors import WorkbenchError
from workbench.metrics.base import Metric, MetricContext, Values

NAME = "bootstrap_nees"
ITERATED = "iterated variance components"
"""The run's cache key where an experiment's resampling keeps its smoother's iterated noise factors
(group -> sigma factor, the diagnosis's group names): the diagnosis then sizes a wrong noise by them."""
MAX_RESAMPLES = 100
"""More resamples per run than this is a typo, not a study (each costs a run of every estimator)."""


def supported(exp: Any) -> bool:
    """Whether the experiment can simulate from its own answer (its ``resample.resample`` and the NEES
    metric named ``metrics.BOOTSTRAP_NEES``)."""
    return (exp.parts.resample is not None
            and exp.parts.bootstrap_nees is not None)


def check(exp: Any, cfg: Any) -> None:
    """A one-line error for a ``--bootstrap`` the experiment cannot honour."""
    b = int(getattr(cfg, "bootstrap", 0) or 0)
    if b == 0:
        return
    if not 0 < b <= MAX_RESAMPLES:
        raise WorkbenchError(f"--bootstrap: resamples per run from 1 to {MAX_RESAMPLES}, got {b}")
    if not supported(exp):
        raise WorkbenchError(f"--bootstrap: the {exp.name} experiment cannot simulate from its own answer yet")


def metric(exp: Any) -> Metric:
    """The ``bootstrap_nees`` row of an experiment that supports it (the dimension of its NEES)."""
    own = {m.name: m for m in exp.parts.metrics}
    nees = own[exp.parts.bootstrap_nees]
    return Metric(NAME, _nees, "",
                  f"the NEES ({nees.dimension} dof) of the estimator on datasets simulated from the run's own answer, "
                  "mean over each resample's steps (truth-free: see workbench.metrics.bootstrap)",
                  reduce="mean", dimension=nees.dimension, independent=True, truth_free=True, window=False)


def rows(exp: Any, cfg: Any) -> list[Metric]:
    """The ``bootstrap_nees`` row where the config asks for resamples; none otherwise; a one-line
    error where the experiment cannot make them (:func:`check`)."""
    if cfg is None or not getattr(cfg, "bootstrap", 0):
        return []
    check(exp, cfg)
    return [metric(exp)]


def carry(result: Any, summary: Any) -> None:
    """The run's smoother's iterated noise factors, where its bootstrap made them (:data:`ITERATED`),
    into that smoother's evidence (``Evidence.iterated``): the diagnosis then sizes a wrong noise by
    them."""
    from workbench.metrics import truthfree

    iterated = result.cache.get(ITERATED)
    ref = truthfree.smoother(result.estimators, result.estimates)
    if isinstance(iterated, dict) and ref in summary.evidence:
        summary.evidence[ref].iterated = [dict(iterated)]


def into_diagnosis(found: dict, entry: Mapping[str, Any]) -> None:
    """The parametric bootstrap's NEES (:mod:`.bootstrap`), where the run made one, into a diagnosis:
    ``bootstrap_nees`` with its band and ``covers`` (inside it: the estimator's covariance covers
    its error on data like these). A noise the data find right with a NEES over its band is the
    linearisation's fault, not the noise's: the verdict is then **overconfident** (under it,
    **conservative**)."""
    v, band = entry.get("bootstrap_nees"), entry.get("bootstrap_nees_band")
    if v is None or band is None:
        return
    found["bootstrap_nees"], found["bootstrap_nees_band"] = v, band
    found["covers"] = bool(band[0] <= v <= band[1])
    said = (f"bootstrap NEES {v:.3g} against {band[0]:.3g}-{band[1]:.3g}: its covariance "
            + ("covers its error on data simulated from its answer" if found["covers"] else
               "understates its error on data simulated from its answer" if v > band[1] else
               "overstates its error on data simulated from its answer"))
    if found["verdict"] == "consistent" and not found["covers"]:
        found["verdict"] = "overconfident" if v > band[1] else "conservative"
        found["consistent"] = False
        found["reason"] = (f"the noise fits the data, but its covariance {'under' if v > band[1] else 'over'}states "
                           "its error (a linearisation the geometry bends, or a covariance not its own): "
                           f"{said}; {found['reason']}")
    else:
        found["reason"] = f"{found['reason']}; {said}"


def _nees(data: Any, est: Any, ctx: MetricContext) -> Values | None:
    found = ctx.shared("bootstrap", lambda: resampled(ctx.result.experiment, ctx))
    return found.get(ctx.name)


def resampled(exp: Any, ctx: MetricContext) -> dict[str, Values]:
    """Every estimator's bootstrap NEES of one run (the module's text): estimator -> one figure per
    resample (NaN where it failed on one)."""
    from workbench.core.estimator import RunContext, estimate_all
    from workbench.metrics.statistics import counted

    cfg = ctx.cfg
    resample = exp.parts.resample
    own = {m.name: m for m in exp.parts.metrics}
    nees = own[exp.parts.bootstrap_nees]
    rows = [e for e in ctx.estimators.values() if e.name in ctx.estimates]
    plain = dataclasses.replace(cfg, bootstrap=0)
    rng = np.random.default_rng([int(cfg.seed), int(ctx.run), 0xB0075])
    out: dict[str, list[float]] = {e.name: [] for e in rows}
    for _ in range(int(cfg.bootstrap)):
        data = resample(ctx.result, cfg, rng)
        estimates, _ = estimate_all(rows, exp.assumed(data, plain), plain, RunContext(ctx.run), exp.check)
        mctx = MetricContext(plain, ctx.run, estimates=estimates, estimators={e.name: e for e in rows})
        for e in rows:
            v = None
            if e.name in estimates:
                v = nees(data, estimates[e.name], dataclasses.replace(mctx, name=e.name, estimator=e))
            x = counted(v, exp.settle(plain), nees) if v is not None else np.array([np.nan])
            out[e.name].append(float(np.nanmean(x)) if np.isfinite(x).any() else np.nan)
    return {n: Values(np.array(v, float), dof=nees.dimension) for n, v in out.items()}
