"""The whole log's optimum for ``--tune-noise``, found at the scale of its own intervals, and the
likelihood-ratio sides of those intervals.

**The last step** (:func:`polished`). The values are first moved to the whole log's optimum by a
Newton step whose gradient comes from the Hessian's runs, a factor 1.5 apart
(:data:`.selftune.H_STEP`: wide, for a SLAM filter's jumps). For a value the data pin down to a few
per cent that step is many of its standard deviations, and the central difference reads the NLL's
skew as a slope: for a Gaussian's log-sigma the third derivative's ``f3 h^2 / 6`` over the
curvature, about 0.055 in the logarithm at that step, where sea's azimuth and elevation sigmas have
a standard deviation of 0.026-0.03 (sea's simulation, seed 2: the NLL fell by 1.6-2.0 one standard
deviation below that step's answer in both). One more Newton step, its gradient by central
differences one standard deviation wide (each value's own, from the Hessian; ``2n`` runs, at once),
leaves ``1 / 6n`` of that error.

**The likelihood-ratio sides** (:func:`widened`). A noise's likelihood is skewed in its logarithm:
a Gaussian's NLL in a log-sigma ``x`` is ``n x + S e^(-2x) / 2``, steep toward a small sigma and
shallow toward a large one, so over a few tens of effective measurements the maximum-likelihood
estimate sits low more often than high, and a Wald interval ``x +- 1.96 sd``, symmetric, misses the
truth above it more often than 2.5 % (sea's acceleration, whose likelihood sees about 18 effective
measurements: its Wald intervals covered 141 of 160 tunings, 88 %,
``benchmarks/tune_noise_recovery.py --cases sea``, seeds 0-79). The likelihood-ratio interval, where
the profile NLL has risen by ``chi2_1(0.95) / 2 = 1.92`` (Pawitan, *In All Likelihood*, 2001, sec.
2.6 and 3.4; Venzon and Moolgavkar, *Appl. Statist.* 37, 1988), follows the skew.

The profile is walked along the quadratic's trace (each value moved with the others at their
conditional optimum under the Hessian: ``d = C e_i / C_ii``, ``C = H^-1``), one secant step in
``sqrt(rise)`` from the Wald end (two filter runs per value, run at once): along that line the NLL
is at least the profile's, so the end it finds is inside the profile's. Each side is therefore the
farther of the Wald end (with the sandwich's width, :func:`.selftune.intervals`) and the likelihood
ratio's (widened by the same sandwich factor: a model not quite the data's spreads its estimate
more than its likelihood says, Royall 1986), and at most :data:`REACH` times the Wald half-width: a
side that hardly rises is a flat likelihood, which the identification has judged."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

Z95 = 1.959964
RISE = Z95 ** 2 / 2    # the NLL's rise at a 95 % likelihood-ratio bound (chi-square, 1 dof, over 2)
REACH = 2.0            # a side at most this many Wald half-widths
POLISH_REACH = 3.0     # the last step at most this many standard deviations of each value


def _block(H: np.ndarray, identified: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The identified values' indices, their block of ``H`` (symmetrised) and its inverse (None
    where there is none)."""
    idx = np.flatnonzero(identified)
    sub = 0.5 * (H[np.ix_(idx, idx)] + H[np.ix_(idx, idx)].T)
    if idx.size == 0:
        return idx, sub, None
    try:
        return idx, sub, np.linalg.inv(sub)
    except np.linalg.LinAlgError:
        return idx, sub, None


def polished(f: Any, x: np.ndarray, H: np.ndarray, identified: np.ndarray,
             prefetch: Any = None) -> np.ndarray:
    """``x`` moved by one Newton step on the identified values, its gradient by central
    differences one standard deviation (``sqrt(C_ii)``, ``C`` the inverse of ``H``'s identified
    block) wide, the step at most :data:`POLISH_REACH` of them in any value and kept only where
    ``f`` descends (halved once where it does not)."""
    idx, sub, C = _block(H, identified)
    f0 = f(x)
    if C is None or not np.isfinite(f0):
        return x
    sd = np.sqrt(np.diag(C))
    if not (np.isfinite(sd).all() and (sd > 0).all()):
        return x
    unit = np.eye(len(x))
    points = [x + side * s * unit[i] for i, s in zip(idx, sd, strict=True) for side in (1, -1)]
    if prefetch is not None:
        prefetch(points)
    g = np.array([(f(points[2 * k]) - f(points[2 * k + 1])) / (2 * s) for k, s in enumerate(sd)])
    if not np.isfinite(g).all():
        return x
    step = -np.linalg.solve(sub, g)
    step *= min(1.0, POLISH_REACH / max(float(np.max(np.abs(step) / sd)), 1e-300))
    for _ in range(2):
        y = x.copy()
        y[idx] += step
        if f(y) < f0:
            return y
        step = step / 2
    return x


def widened(f: Any, x: np.ndarray, H: np.ndarray, bounds: np.ndarray, identified: np.ndarray,
            prefetch: Any = None) -> np.ndarray:
    """``bounds`` (``(n, 2)``, the Wald intervals about ``x``) each side moved out to the
    likelihood ratio's bound where that is farther; ``H``: the curvature the Wald intervals were
    read from (the identified values' block is inverted); ``f``: the NLL of the log-values."""
    idx, _, C = _block(H, identified)
    out = np.array(bounds, float)
    if C is None or not np.isfinite(f0 := f(x)):
        return out
    plan = []
    for pos, i in enumerate(idx):
        s = math.sqrt(C[pos, pos]) if C[pos, pos] > 0 else math.nan
        lo, hi = out[i]
        wald = (math.log(hi) - math.log(lo)) / (2 * Z95) if lo > 0 and hi > 0 else math.nan
        if not (math.isfinite(s) and math.isfinite(wald)):
            continue
        d = np.zeros(len(x))
        d[idx] = C[:, pos] / C[pos, pos]
        plan.append((i, d, s, max(wald / s, 1.0)))
    if prefetch is not None:
        prefetch([x + side * Z95 * s * d for _, d, s, _ in plan for side in (1, -1)])
    first = {(i, side): f(x + side * Z95 * s * d) - f0 for i, d, s, _ in plan for side in (1, -1)}
    second = {}
    for i, _d, s, _ in plan:
        for side in (1, -1):
            rise = first[i, side]
            if math.isfinite(rise) and rise < RISE:
                second[i, side] = side * Z95 * s * math.sqrt(RISE / max(rise, RISE / REACH ** 2))
    if prefetch is not None:
        prefetch([x + t * d for i, d, _, _ in plan for side in (1, -1) if (t := second.get((i, side))) is not None])
    for i, d, s, k in plan:
        for side in (1, -1):
            t1 = second.get((i, side))
            if t1 is None:
                continue
            t0, r0, r1 = side * Z95 * s, first[i, side], f(x + t1 * d) - f0
            # the secant in sqrt(rise), which a quadratic makes linear in t
            a0, a1 = math.sqrt(max(r0, 0.0)), math.sqrt(max(r1, 0.0)) if math.isfinite(r1) else math.nan
            t = t1 + (t1 - t0) * (math.sqrt(RISE) - a1) / (a1 - a0) if math.isfinite(a1) and a1 > a0 else t1
            t = side * min(abs(t), REACH * Z95 * s)
            if side > 0:
                out[i, 1] = max(out[i, 1], math.exp(x[i] + k * t))
            else:
                out[i, 0] = min(out[i, 0], math.exp(x[i] + k * t))
    return out
