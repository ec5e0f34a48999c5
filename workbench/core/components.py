"""The smoother's own evidence on ``--tune-noise``'s values (:mod:`workbench.core.selftune`):
variance component estimation from a batch smoother's residuals by group (Förstner 1979; Koch,
*Parameter Estimation and Hypothesis Testing in Linear Models*, sec. 3.6), robust where a gate
judged the group, iterated while it contracts."""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any

import numpy as np

VCE_ITERATIONS = 4      # smoother runs at most
VCE_SETTLED = 0.05      # a group's factor within 5 % of one: the fixed point
VCE_CONTRACTION = 0.5   # each step's largest log-factor at most half the last's, or the iteration stops


def component(res: Any, group: str) -> tuple[float, tuple[float, float]] | None:
    """A residual group's variance factor and its 95 % interval: Förstner's ``sum r2 /
    redundancy`` over the used residuals (:func:`workbench.estimation.noisefit.variance_components`)
    for a group no gate touches (the odometry), and for the measurements a gate judged a robust
    one: each used residual studentised by the group's redundancy share (``r2 / (redundancy /
    n)``, whose mean is its dimension where the noise is what was assumed), the ones the gate
    left out as they are, and the core's factor of a chi-square scale mixture fitted to them all
    (:func:`workbench.estimation.noisefit.fit`: a heavy tail, outliers, fitted as a tail). A plain
    sum over the used ones is fooled twice by a gate: it misses the outliers the gate left out,
    and it shrinks the noise each round as the gate, told the smaller noise, leaves out more
    (measured on MRCLAM robot 1: a bearing sigma 1 -> 0.27 deg in four rounds, not settled). The
    mixture is not for the odometry: many of its residuals are a stopped robot's, near nought,
    which a core-and-tail fit reads as a core far narrower than the noise (measured there: a speed
    sigma of 2e-8)."""
    from workbench.estimation.noisefit import fit, variance_components

    mine = (res.group == group) & np.isfinite(res.r2)
    used = mine & res.used
    n = float(res.dof[used].sum())
    red = float(res.redundancy.get(group, 0.0))
    if n <= 0 or red <= 1.0:
        return None
    if group != res.measurement or res.used[mine].all():
        return variance_components(res.r2[used], red)
    q = res.r2.astype(float).copy()
    q[used] /= red / n
    got = fit(q[mine], res.dof[mine], tail=True)
    if got is None or "k" not in got.intervals:
        return None
    return got.k, got.intervals["k"]


def vce(exp: Any, data: Any, cfg: Any, smoother: str, groups: dict[str, list[str]], values: dict[str, float],
        bounds: np.ndarray, names: list[str]) -> dict:
    """The smoother's values by iterated variance component estimation from the filter's
    ``values`` (``groups``: a residual group -> the tuned values that scale its noise), each with
    its 95 % interval, and where they disagree with the filter's (``bounds``, rows in ``names``)."""
    t0 = time.perf_counter()
    now = dict(values)
    total = {g: 1.0 for g in groups if groups[g]}
    band: dict[str, tuple[float, float]] = {}
    runs = 0
    previous, settled, diverged = math.inf, False, False
    for _ in range(VCE_ITERATIONS):
        told = dataclasses.replace(cfg, **{f"assume_{k}": float(v) for k, v in now.items()})
        estimates, failed = exp.estimate(data, told, [smoother])
        runs += 1
        res = getattr(estimates.get(smoother), "residuals", None)
        if smoother in failed or res is None:
            return {"smoother": smoother, "failed": failed.get(smoother, "it gave no residuals"), "runs": runs}
        got = {g: c for g in total if (c := component(res, g)) is not None}
        size = max((abs(math.log(f)) for f, _ in got.values()), default=0.0)
        if size > VCE_CONTRACTION * previous:   # the fixed point runs away: the last values stand
            diverged = True
            break
        previous = size
        for g, (f, (lo, hi)) in got.items():
            total[g] *= f
            band[g] = (total[g] / f * lo, total[g] / f * hi)
            for k in groups[g]:
                now[k] *= math.sqrt(f)
        settled = size <= math.log1p(VCE_SETTLED)
        if settled:
            break
    out_values, interval, disagree, compared = {}, {}, [], []
    for g, ks in groups.items():
        for k in ks:
            if g not in band:
                continue
            out_values[k] = now[k]
            lo, hi = (values[k] * math.sqrt(b) for b in band[g])
            interval[k] = [lo, hi]
            flo, fhi = bounds[names.index(k)]
            if math.isfinite(flo) and math.isfinite(fhi):
                compared.append(k)
                if hi < flo or lo > fhi:
                    disagree.append(k)
    return {"smoother": smoother, "values": out_values, "interval": interval,
            "factor": {g: total[g] for g in band}, "runs": runs, "settled": bool(settled), "diverged": diverged,
            "seconds": time.perf_counter() - t0, "disagree": disagree,
            "compared": compared}
