"""``--tune-noise``: the noise the data can identify, estimated on the data themselves by the
likelihood of a filter's innovations, before every estimator runs with it.

What is tuned is the experiment's to say (its package's ``run.tunable(data, cfg)``: the filter
whose innovations give the likelihood, the noise settings with the data's own values as the
start, and the settings it leaves with why). The search is Nelder-Mead on the logarithms of the
values (the likelihood of the same data is a smooth, deterministic function of them: no sampling
noise to average), its first simplex a factor of two about the start in each direction, stopped
when the values move by under 3 % or after ``MAX_EVALUATIONS`` filter runs. The objective is the
filter's NLL with a gated measurement charged as its least likely kept one
(:meth:`~workbench.estimation.consistency.Innovations.charged_nll`), so it cannot be won by gating
the data away. The data are run 0's (a real log is one run); the values found are what the
estimators assume (``assume_*``) in every run.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np

from workbench.errors import WorkbenchError

MAX_EVALUATIONS = 80
STEP = math.log(2.0)   # the first simplex: a factor of two about the start
XATOL = 0.03           # the values' relative change (3 %) at which the search stops


def nll(exp: Any, data: Any, cfg: Any, filt: str, values: dict[str, float]) -> float:
    """The filter's charged NLL of ``data`` told ``values`` (config fields without ``assume_``)."""
    told = dataclasses.replace(cfg, **{f"assume_{k}": float(v) for k, v in values.items()})
    estimates, failed = exp.estimate(data, told, [filt])
    if filt in failed:
        return math.inf
    innov = getattr(estimates[filt], "innovations", None)
    if innov is None:
        raise WorkbenchError(f"--tune-noise: {filt} reports no innovations on this data")
    terms = innov.charged_nll()
    return float(np.nansum(terms)) if np.isfinite(terms).any() else math.inf


def tune_noise(exp: Any, cfg: Any) -> tuple[Any, dict]:
    """``cfg`` with the tuned values as what the estimators assume, and the report (the values
    before and after, the NLL before and after, the evaluations, the seconds, what was left)."""
    tunable = exp._optional("run", "tunable")
    if tunable is None:
        raise WorkbenchError(f"--tune-noise: {exp.name}'s estimators report no innovations, so there is no "
                             "likelihood of the data to tune by")
    t0 = time.perf_counter()
    data = exp.dataset(cfg, 0)
    filt, start, left = tunable(data, cfg)
    given = {k: getattr(cfg, f"assume_{k}") for k in start if getattr(cfg, f"assume_{k}", None) is not None}
    start = {**start, **given}    # what the user says the estimators assume is the start
    names = list(start)
    x0 = np.log([start[n] for n in names])
    cache: dict[tuple, float] = {}

    def f(x: np.ndarray) -> float:
        key = tuple(np.round(x, 12))
        if key not in cache:
            cache[key] = nll(exp, data, cfg, filt, dict(zip(names, np.exp(x), strict=True)))
        return cache[key]

    from scipy.optimize import minimize

    before = f(x0)
    if not math.isfinite(before):
        raise WorkbenchError(f"--tune-noise: {filt} has no likelihood of this data at the start values")
    simplex = np.vstack([x0, x0 + STEP * np.eye(len(x0))])
    res = minimize(f, x0, method="Nelder-Mead", options={"initial_simplex": simplex, "xatol": XATOL,
                                                        "fatol": 1e-3, "maxfev": MAX_EVALUATIONS})
    best = res.x if res.fun <= before else x0
    values = dict(zip(names, (float(v) for v in np.exp(best)), strict=True))
    report = {"filter": filt, "start": start, "tuned": values, "nll_start": before,
              "nll_tuned": float(min(res.fun, before)), "evaluations": len(cache),
              "seconds": time.perf_counter() - t0, "converged": bool(res.success), "left": left}
    return dataclasses.replace(cfg, **{f"assume_{k}": v for k, v in values.items()}), report


def lines(report: dict) -> list[str]:
    """The report as the command prints it."""
    said = ", ".join(f"{k.replace('_', '-')} {report['start'][k]:.4g} -> {v:.4g}" for k, v in report["tuned"].items())
    out = [f"tuned noise (the likelihood of {report['filter']}'s innovations on run 0, {report['evaluations']} "
           f"evaluations, {report['seconds']:.1f} s{'' if report['converged'] else ', not converged'}): {said}; "
           f"NLL {report['nll_start']:.1f} -> {report['nll_tuned']:.1f}"]
    out += [f"not tuned: {k.replace('_', '-')}: {why}" for k, why in report["left"].items()]
    return out
