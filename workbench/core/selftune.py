"""``--tune-noise``: the noise the data can identify, estimated on the data themselves by the
likelihood of a filter's innovations, cross-validated, each value with its 95 % interval, before
every estimator runs with it.

What is tuned is the experiment's to say (its package's ``run.tunable(data, cfg)``: the filter
whose innovations give the likelihood, the noise settings with the data's own values as the
start, and the settings it leaves with why).

* **The objective** is the filter's negative log-likelihood of the data (the prediction-error
  decomposition: Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
  Navigation*, sec. 5.4; LowLevelParticleFilters.jl's ``autotune_covariances`` maximises the same)
  with a gated measurement charged as its part's least likely kept one
  (:meth:`~workbench.estimation.consistency.Innovations.charged_nll`), so it cannot be won by gating
  the data away.
* **The search** runs on the logarithms of the values (positive, and a factor is a step): first
  coordinate sweeps (:func:`_sweeps`: one value at a time by a bounded Brent search, which crosses
  a start ten times off), then a joint search, one of two: ``"nelder-mead"`` (its first simplex a
  factor of 1.4 about the sweeps' answer, stopped when the values move by under 3 %) or
  ``"lbfgs"`` (L-BFGS-B with forward-difference gradients). The likelihood is not smooth: a gate
  passes a measurement or not, and a SLAM filter's rows change as it initialises a landmark
  sooner or later (jumps of about a unit of NLL), which finite-difference gradients read as
  slopes. The default, :data:`METHOD`, is the one measured right in fewer runs
  (``benchmarks/tune_noise_recovery.py --method``).
* **The rows held**: where the experiment can hold its filter's rows (its package's
  ``hold_rows``: omni's EKF, each landmark initialised at the step one run initialised it,
  :class:`~workbench.experiments.omni.algorithms.ekf.HeldInit`), each joint search (at most
  :data:`HOLD_ROUNDS`) runs with the rows the filter makes where the sweeps or the last search
  ended (the sweeps, which cross a start's factor of ten, with none); the curvature, the intervals
  and the held-out part with those at the first part's answer. The likelihood is then conditional on where the
  landmarks entered, as one is on a data association, and smooth in the noise. Measured on the
  paper's bicycle over 120 s (``benchmarks/tune_noise_recovery.py --logs 5 --cases bicycle``,
  2026-12-07, 10 tunings): the steering's and the bearing's intervals cover the truth in 10 and 9
  of 10 where 4 and 5 did, both within 25 % in 10 of 10 (8 and 10), and the two starts of one log
  land together (seed 2's steering 2.78 from x0.1 and from x10, where 3.32 and 2.38); over 20 logs,
  covered in 37 and 36 of 40 (docs/tuning.md).
* **Cross-validated**: the values are tuned on the first :data:`FIT_SHARE` of the measurements (by
  time); the rest's predictive likelihood (the filter runs on through it: each term is that of a
  measurement not yet seen) is reported at the start values and the tuned ones. The values are
  then moved to the whole log's optimum by a Newton step from the first part's (the Hessian's
  runs give the gradient too; the step at most a factor 2.25, halved twice where it does not
  descend, then the joint search), and those are what the estimators
  assume, unless the held-out part's likelihood is no better at them than at the start: then
  the start values are kept (measured on MRCLAM robot 3: a bearing sigma of 0.15 deg fitted the
  first three quarters and doubled the rest's NLL).
* **Identified**: the Hessian of the whole log's NLL in the log-values at the first part's
  optimum (central differences, a step of :data:`H_STEP`: wide, since a SLAM filter's objective
  jumps by about a unit as its rows change with the noise, which a small step reads as
  curvature; at a factor 1.5 a Gaussian's curvature in a log-sigma reads 5 % high,
  ``sinh(h)^2 / h^2``) is the observed Fisher information; its inverse the covariance of the
  log-values (Pawitan, *In All Likelihood*, 2001, sec. 2.7 and 3.3), its curvature taken
  :data:`CURVED` of what the step reads; where the per-measurement scores say the estimate varies
  more than that (a model not quite the data's: the sandwich ``H^-1 J H^-1``, :func:`scores`), the
  sandwich's variance is taken instead. Each value's 95 % interval is ``exp(x +- 1.96 sd)``
  (:func:`intervals`), about the whole log's optimum found at the interval's own scale and each side
  out to the likelihood ratio's bound where the NLL rises slower than the curvature says
  (:mod:`.optimum`). Measured on sea's simulation (``benchmarks/tune_noise_recovery.py --cases
  sea``): on 40 logs the Hessian's alone covered 87.5 % of the time (over the logs the estimates
  spread 1.16-1.21 times its sd), with the sandwich 89-97.5 %; on 80 logs with the last step and
  the likelihood ratio's sides 94-100 % (the acceleration 150 of 160 tunings, where 141). A value
  whose interval spans more than a factor of :data:`SPAN`, whose curvature is not positive, or
  along which the likelihood is not smooth
  (:func:`rough`: the curvature at twice the step differs by more than :data:`ROUGH`; measured on
  the paper's bicycle SLAM, where the speed sigma's "interval" missed the truth in 17 of 20 logs)
  is *not identified by these data*: it is held at its start (what the user or the data said)
  while the rest are refined without it, and it is not told (the config keeps what it had).
* **The smoother's own evidence**: where the experiment names a smoother with residuals by group
  (its package's ``run.components``), variance component estimation (Förstner 1979; Koch,
  *Parameter Estimation and Hypothesis Testing in Linear Models*, sec. 3.6) from its answer at the
  filter's values: each group's factor (``sum r2 / redundancy``; for the gated bearings a robust
  one, :mod:`.components`) scales the group's noise, iterated to a fixed
  point while it contracts (each step's largest factor at most half the last's, in logarithms:
  on MRCLAM a smoother told a narrower noise gates more and lands elsewhere, and the iteration
  ran a bearing sigma to 85 deg; the last contracting step's values stand, marked). VCE rather
  than EM in the smoother (Wong et al., RA-L 2020): a batch GTSAM smoother is a least-squares
  adjustment whose redundancy per group is at hand (:mod:`workbench.estimation.redundancy`), each
  step is one smoother run, and it needs no marginal covariances of the whole trajectory, which
  EM's expectation step does. The filter's and
  the smoother's values are compared; where their intervals do not meet, the report says so (an
  EKF's linearisation on a long loop inflates what it needs; a smoother relinearises); where they
  differ by more than a factor :data:`SPAN`, nothing is told (one of the two is wrong, and the
  data cannot say which).
* **What the data do not reject is not told**: where every identified value's 95 % interval (out to
  the likelihood ratio's bound) holds its start, the start stands, as a test of each at 5 % keeps
  it, and the report says so; where one excludes its start, the joint optimum is told. A noise the
  user or the scenario gave is thus changed only where the data contradict it.

The data are run 0's (a real log is one run); the values found are what the estimators assume
(``assume_*``) in every run. The Hessian's and the roughness's runs, independent of one another, are
shared by two forked processes (:meth:`.objective._Objective.prefetch`); with the EKF's odometry read
once per run in its own frame (:class:`~workbench.experiments.omni.motion.Stretches`) and its
propagation and update compiled (:mod:`~workbench.experiments.omni.algorithms.bearing_update`) a
MRCLAM 6 robot tunes in 19-36 s where it took 41-86 (``benchmarks/tune_noise_mrclam.py``).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from typing import Any

import numpy as np

from workbench.core import optimum
from workbench.core.components import vce
from workbench.core.objective import Terms, _Objective, terms  # noqa: F401 (Terms, terms: this module's API)
from workbench.core.threads import on_one_blas_thread
from workbench.errors import WorkbenchError

MAX_EVALUATIONS = 60     # the joint search's budget on the first part (half that for each refinement)
STEP = math.log(2.0)   # the first simplex: a factor of two about the start
XATOL = 0.03           # the values' relative change (3 %) at which Nelder-Mead stops
FIT_SHARE = 0.75       # the first part of the measurements (by time) the values are tuned on
H_STEP = math.log(1.5)  # the Hessian's step in the log-values (a factor 1.5)
CURVED = (H_STEP / math.sinh(H_STEP)) ** 2   # a Gaussian's curvature in a log-sigma reads 1 / CURVED at that step
SPAN = 3.0             # a 95 % interval wider than this factor: not identified
ROUGH = 2.0            # the curvature at twice the step off by more than this factor: not identified
Z95 = optimum.Z95     # the standard normal's 97.5 % point (one constant, here and in :mod:`.optimum`)
REACH = math.log(30.0)  # the coordinate sweeps reach a factor of 30 either way
SWEEPS = 2
HOLD_ROUNDS = 2         # joint searches at most, the second with the rows the first ended at held
SWEEP_XATOL = 0.1       # the sweeps stop at 10 %: the joint search refines
METHODS = ("nelder-mead", "lbfgs")
METHOD = "nelder-mead"


def _sweeps(f: Any, x0: np.ndarray, reach: float = REACH, sweeps: int = SWEEPS) -> np.ndarray:
    """Coordinate descent: each log-value in turn by a bounded Brent search within ``reach`` of
    where it is (the others held), ``sweeps`` times or until none moves by 10 %. It crosses the
    factors of ten a start can be off by where a simplex crawls: far from its optimum a filter
    is told a noise it cannot live with (a bearing sigma ten times too small makes the EKF diverge)
    and a joint step finds no descent, while one noise at a time does."""
    from scipy.optimize import minimize_scalar

    x = np.asarray(x0, float).copy()
    for _ in range(sweeps):
        moved = False
        for i in range(len(x)):
            def g(z: float, i: int = i) -> float:
                y = x.copy()
                y[i] = z
                return f(y)

            here = g(x[i])
            with np.errstate(invalid="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)   # an inf where the filter fails
                res = minimize_scalar(g, bounds=(x[i] - reach, x[i] + reach), method="bounded",
                                      options={"xatol": SWEEP_XATOL, "maxiter": 10})
            if np.isfinite(res.fun) and res.fun < here and abs(res.x - x[i]) > SWEEP_XATOL:
                x[i], moved = float(res.x), True
        if not moved:
            break
    return x


def _minimise(f: Any, x0: np.ndarray, method: str, budget: int, step: float) -> tuple[np.ndarray, float, bool]:
    """The minimum of ``f`` from ``x0`` by ``method`` (:data:`METHODS`) within about ``budget``
    evaluations: its point, value and whether the search says it converged."""
    from scipy.optimize import minimize

    if method == "lbfgs":
        how = {"method": "L-BFGS-B", "options": {"eps": 0.01, "maxfun": budget, "ftol": 1e-7, "gtol": 1e-3}}
    else:
        simplex = np.vstack([x0, x0 + step * np.eye(len(x0))])
        how = {"method": "Nelder-Mead", "options": {"initial_simplex": simplex, "xatol": XATOL, "fatol": 1e-3,
                                                    "maxfev": budget}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # an inf where the filter fails
        res = minimize(f, x0, **how)
    return np.asarray(res.x, float), float(res.fun), bool(res.success)


def hessian(f: Any, x: np.ndarray, h: float = H_STEP, prefetch: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Central differences of ``f`` at ``x``, its Hessian and its gradient (the same runs): ``2n``
    runs for the diagonal and the gradient, four per pair off it (``prefetch``: given every point
    first, to run them at once)."""
    n = len(x)
    H = np.zeros((n, n))
    g = np.zeros(n)
    e = np.eye(n) * h
    if prefetch is not None:
        prefetch([x] + [x + sign * e[i] for i in range(n) for sign in (1, -1)]
                 + [x + a * e[i] + b * e[j] for i in range(n) for j in range(i) for a in (1, -1) for b in (1, -1)])
    f0 = f(x)
    for i in range(n):
        up, down = f(x + e[i]), f(x - e[i])
        H[i, i] = (up - 2 * f0 + down) / h ** 2
        g[i] = (up - down) / (2 * h)
        for j in range(i):
            H[i, j] = H[j, i] = (f(x + e[i] + e[j]) - f(x + e[i] - e[j]) - f(x - e[i] + e[j])
                                 + f(x - e[i] - e[j])) / (4 * h * h)
    return H, g


def rough(f: Any, x: np.ndarray, H: np.ndarray, h: float = H_STEP, prefetch: Any = None) -> np.ndarray:
    """The values along which ``f`` is not the smooth bowl a curvature reads: the diagonal
    curvature at twice the step against the Hessian's (``2n`` more runs). A smooth likelihood's
    agree within 17 % (a Gaussian's in a log-sigma: ``sinh(2h)^2 / 4h^2`` against ``sinh(h)^2 /
    h^2``); where the filter's rows change with the noise (a landmark initialised sooner or later)
    a unit's jump reads four times less curved at twice the step. Where the step's curvature is
    more than :data:`ROUGH` times that at twice the step it is not the information, and the value
    is not identified."""
    out = np.zeros(len(x), bool)
    if prefetch is not None:
        prefetch([x + sign * 2 * h * e for e in np.eye(len(x)) for sign in (1, -1)])
    f0 = f(x)
    for i in range(len(x)):
        e = np.zeros(len(x))
        e[i] = 2 * h
        wide = (f(x + e) - 2 * f0 + f(x - e)) / (2 * h) ** 2
        near = H[i, i]
        # (more curved at twice the step is a wall, as a filter told too small a noise diverges:
        # the interval from the step's curvature is then the wider, not the narrower)
        out[i] = not (np.isfinite(near) and near > 0 and (not np.isfinite(wide) or near / max(wide, 1e-300) <= ROUGH))
    return out


def scores(obj: Any, x: np.ndarray, h: float = H_STEP, lags: int | None = None) -> np.ndarray | None:
    """The per-measurement scores' outer product ``J (n, n)`` of the NLL at ``x``, the "meat" of
    the sandwich ``H^-1 J H^-1`` (Huber 1967; White 1982): the covariance of a maximum-likelihood
    estimate whose model is not quite the data's (Pawitan, *In All Likelihood*, 2001, sec. 13.4),
    which the Hessian alone understates.

    Each measurement's score is its term's central difference over the Hessian's runs (cached by
    :func:`hessian`: no run more); centred, and summed with its neighbours' up to ``lags``
    apart by Newey and West's weights (1987; by default ``4 (N / 100)^(2/9)``), since a filter's
    scores are correlated where its model is wrong. Only measurements every run used count. None
    where the runs do not share their rows (a SLAM filter's can change with the noise) or fewer
    than ``10 n`` remain.

    The step's difference is not undone: a measurement's own sigma reads ``sinh(2h) / 2h`` steeper at
    ``h`` (1.11 at a factor 1.5), which leaves the sandwich up to 10 % wide in variance where the model
    is right, while a motion noise, which enters a term through the state's covariance, reads less
    so; undone by a Gaussian's factor, sea's acceleration intervals covered 36 of 40 tunings rather
    than 38 (``benchmarks/tune_noise_recovery.py --cases sea``). A wide side is the safe one."""
    n = len(x)
    runs = [(obj.run(x + h * e), obj.run(x - h * e)) for e in np.eye(n)]
    if any(r is None for pair in runs for r in pair):
        return None
    t = runs[0][0].t
    if any(not np.array_equal(r.t, t) for pair in runs for r in pair):
        return None
    ok = np.ones(len(t), bool)
    for pair in runs:
        for r in pair:
            ok &= r.used & np.isfinite(r.nll)
    if np.count_nonzero(ok) < 10 * n:
        return None
    G = np.column_stack([(up.nll[ok] - down.nll[ok]) / (2 * h) for up, down in runs])
    G -= G.mean(axis=0)
    lags = int(4 * (len(G) / 100) ** (2 / 9)) if lags is None else lags
    J = G.T @ G
    for lag in range(1, lags + 1):
        C = G[lag:].T @ G[:-lag]
        J += (1 - lag / (lags + 1)) * (C + C.T)
    return J


def intervals(H: np.ndarray, x: np.ndarray, drop: np.ndarray | None = None,
              J: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each value's 95 % interval ``(n, 2)`` from the Hessian ``H`` of the NLL in the log-values at
    ``x``, and whether it is identified (an interval spanning at most :data:`SPAN`).

    The values are dropped one at a time, each then held fixed (as a value not identified is:
    kept at its start, the rest refined without it): first any whose row of ``H`` is not finite
    (the filter failed a step away) or whose own curvature is not positive; then, while the rest
    of ``H`` is not positive definite, the value that moves most along its least curved direction
    (a likelihood that jumps as a filter's rows change can read a flat direction as a slightly
    negative one); then, while one's interval spans more than :data:`SPAN`, the widest. The
    intervals of the values kept are those of the rest of ``H`` (conditional on the dropped ones);
    a dropped value's is the one it had when dropped (none where there was none). ``drop``: values
    not identified from the start (:func:`rough`). ``J``: the scores' outer product
    (:func:`scores`); each value's variance is then the larger of the Hessian's and the sandwich's."""
    n = len(x)
    out = np.full((n, 2), np.nan)
    active = np.isfinite(H).all(axis=1) & np.isfinite(H).all(axis=0) & (np.diag(H) > 0)
    if drop is not None:
        active &= ~np.asarray(drop, bool)
    while active.any():
        idx = np.flatnonzero(active)
        sub = 0.5 * (H[np.ix_(idx, idx)] + H[np.ix_(idx, idx)].T)
        w, V = np.linalg.eigh(sub)
        if w[0] <= 1e-9 * abs(w).max():
            active[idx[int(np.argmax(np.abs(V[:, 0])))]] = False
            continue
        C = (V / w) @ V.T
        var = np.diag(C)
        if J is not None and np.isfinite(J).all():
            var = np.maximum(var, np.diag(C @ J[np.ix_(idx, idx)] @ C))
        sd = np.sqrt(var)
        out[idx, 0], out[idx, 1] = np.exp(x[idx] - Z95 * sd), np.exp(x[idx] + Z95 * sd)
        with np.errstate(over="ignore"):   # a flat direction's span is inf: the widest, dropped
            span = np.exp(2 * Z95 * sd)
        if span.max() <= SPAN:
            break
        active[idx[int(np.argmax(span))]] = False
    return out, active


@on_one_blas_thread
def tune_noise(exp: Any, cfg: Any, method: str | None = None) -> tuple[Any, dict]:
    """``cfg`` with the tuned values as what the estimators assume, and the report: the values
    before and after with their 95 % intervals and which are identified, the first part's NLL
    before and after, the held-out part's predictive NLL before and after, the evaluations, the
    seconds and what was left."""
    method = method or METHOD
    if method not in METHODS:
        raise WorkbenchError(f"--tune-noise: the search is one of {', '.join(METHODS)}, not {method!r}")
    tunable = exp.parts.tunable
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
    obj = _Objective(exp, data, cfg, filt, names)
    first = obj.ref = obj.run(x0)
    if first is None or not math.isfinite(first.charged()):
        raise WorkbenchError(f"--tune-noise: {filt} has no likelihood of this data at the start values")
    # the measurements' times (the filter's rows change with the noise: a landmark initialised
    # sooner or later): the first part is up to the time by which FIT_SHARE of them came
    ts = np.sort(first.t[np.isfinite(first.t)])
    split = float(ts[max(0, int(round(FIT_SHARE * len(ts))) - 1)])
    fit, held = (-math.inf, split), (split, math.inf)

    # 1. the first part: coordinate sweeps to the basin, then the joint search; where the filter's
    # rows can be held (:meth:`.objective._Objective.hold_at`), each joint search holds those it
    # makes where the sweeps or the last search ended (HOLD_ROUNDS). The sweeps hold none: they
    # cross the factors of ten a start can be off by, and the rows a filter told such a noise makes
    # are no one's (held from a start x0.1 off, 2 of 20 bicycle logs ended with the steering not
    # identified, or nothing)
    x1 = _sweeps(lambda x: obj.value(x, fit), x0)
    for r in range(HOLD_ROUNDS):
        before = obj.held
        obj.hold_at(x1)
        if r and obj.held == before:
            break
        x1, _, conv1 = _minimise(lambda x: obj.value(x, fit), x1, method, MAX_EVALUATIONS // (1 + r),
                                 STEP / (2 + 2 * r))   # a refinement after the first: half the budget and the simplex
    if obj.value(x1, fit) > obj.value(x0, fit):
        x1 = x0
    # 2. the whole log at the first part's answer (its rows held): its curvature, what the data
    # identify, and a Newton step (within two of the Hessian's steps) to the whole log's optimum
    obj.ref = obj.hold_at(x1) or first

    def whole(x: np.ndarray) -> float:
        return obj.value(x, None)

    H, g = hessian(whole, x1, prefetch=obj.prefetch)
    bounds, identified = intervals(H * CURVED, x1, drop=rough(whole, x1, H, prefetch=obj.prefetch),
                                   J=scores(obj, x1))
    best = x1.copy()
    conv2 = True
    if identified.all():
        step = -np.linalg.solve(0.5 * (H + H.T), g)
        step *= min(1.0, 2 * H_STEP / max(float(np.abs(step).max()), 1e-300))
        for _ in range(3):       # backtracking: the step, its half, its quarter
            if whole(x1 + step) < whole(x1):
                best = x1 + step
                break
            step = step / 2
        else:                    # no descent along it (a rough likelihood): the joint search on the whole log
            best, _, conv2 = _minimise(whole, x1, method, MAX_EVALUATIONS // 2, STEP / 4)
            if whole(best) > whole(x1):
                best = x1.copy()
        bounds = bounds * np.exp(best - x1)[:, None]   # the intervals move with their values
    else:  # 3. the rest kept at its start and the others refined without it
        best[~identified] = x0[~identified]
        free = np.flatnonzero(identified)
        if free.size:
            def sub(z: np.ndarray) -> float:
                x = best.copy()
                x[free] = z
                return obj.value(x, None)

            z, _, conv2 = _minimise(sub, best[free], method, MAX_EVALUATIONS // 2, STEP / 4)
            if sub(z) <= sub(best[free]):
                bounds[free] *= np.exp(z - best[free])[:, None]   # the intervals move with their values
                best[free] = z
    # 4. what does not generalise is not told: the held-out part's predictive likelihood at the
    # first part's values no better than at the start keeps the start
    n_held = int(np.count_nonzero(first.t > split))
    generalises = not n_held or obj.value(x1, held) < obj.value(x0, held)
    if generalises:   # the optimum at the intervals' own scale; each side out to the likelihood ratio's bound
        polished = optimum.polished(whole, best, H * CURVED, identified, prefetch=obj.prefetch)
        bounds, best = bounds * np.exp(polished - best)[:, None], polished
        bounds = optimum.widened(whole, best, H * CURVED, bounds, identified, prefetch=obj.prefetch)
    else:   # nothing tuned stands: no value identified, no interval to compare with
        best = x0.copy()
        bounds = np.full_like(bounds, np.nan)
        identified = np.zeros_like(identified)
    values = dict(zip(names, (float(v) for v in np.exp(best)), strict=True))
    components = exp.parts.components
    smoother = vce(exp, data, cfg, *components(data, cfg, values), values, bounds, names) if components else None
    n_fit = int(np.count_nonzero(first.t <= split))
    report = {"filter": filt, "method": method, "start": start, "tuned": values,
              "interval": {n: [float(a), float(b)] for n, (a, b) in zip(names, bounds, strict=True)},
              "identified": {n: bool(i) for n, i in zip(names, identified, strict=True)},
              "first_part": {"measurements": n_fit, "values": dict(zip(names, map(float, np.exp(x1)), strict=True)),
                             "nll_start": obj.value(x0, fit), "nll_tuned": obj.value(x1, fit)},
              "held_out": {"measurements": n_held, "nll_start": obj.value(x0, held) if n_held else math.nan,
                           "nll_tuned": obj.value(x1, held) if n_held else math.nan, "generalises": generalises},
              "nll_start": obj.value(x0, None), "nll_tuned": obj.value(best, None),
              "evaluations": obj.made, "seconds": time.perf_counter() - t0,
              "converged": bool(conv1 and conv2), "left": left, "smoother": smoother}
    # 5. two estimators' evidence more than a factor SPAN apart: one of them is wrong, and the data
    # cannot say which; nothing is told (measured on MRCLAM robot 5: the EKF's likelihood chose a
    # speed sigma 7x the scenario's, the smoother's variance components a bearing sigma 14x the
    # EKF's; told the EKF's, iSAM2 ended 33 m off)
    contradicted = [k for k, v in ((smoother or {}).get("values") or {}).items()
                    if not 1 / SPAN <= v / values[k] <= SPAN]
    report["contradicted"] = contradicted
    # 6. a value the two disagree on beyond their intervals is not told either: two estimators the
    # noise model makes consistent that differ say the model does not fit the data there (a Hausman
    # test's reading; measured on MRCLAM 6: robot 5's speed sigma, the EKF's 0.140 against the
    # smoother's 0.075, put iSAM2 7.7 m off when told; robot 4's turn sigma put it 1.5 m off, 0.48)
    report["not_told"] = [k for k in (smoother or {}).get("disagree", ()) if k not in contradicted]
    # 7. nor is a start the data do not reject: where every identified value's 95 % interval (out to
    # the likelihood ratio's bound, :func:`.optimum.widened`) holds its start, the start stands, as
    # a test of it at 5 % per value keeps it (the null kept unless the data reject it); where one
    # interval excludes its start, every identified value is told, the joint optimum (told one at a
    # time, robot 1's speed sigma kept and its turn sigma told put iSAM2 0.47 -> 0.56 m). Measured
    # on MRCLAM 6 robot 5: its turn sigma, 1.83 deg (1.15-2.92), told in place of the scenario's 2,
    # put iSAM2 0.43 -> 0.58 m
    tested = [k for k in names if report["identified"][k] and k not in report["not_told"]]
    holds = [report["interval"][k][0] <= start[k] <= report["interval"][k][1] for k in tested]
    report["not_rejected"] = tested if tested and all(holds) else []
    # 8. a value not identified is not told: the config keeps what it had (a real log's outlier share
    # starts at 2 % where the config has no outlier model; told at that start, MRCLAM 6 robot 5's EKF
    # went 0.66 -> 1.42 m)
    kept = report["not_told"] + report["not_rejected"]
    told = {} if not generalises or contradicted else {
        k: v for k, v in values.items() if report["identified"][k] and k not in kept}
    report["told"] = told   # none: the config as it came (a search's start is not told either)
    return (dataclasses.replace(cfg, **{f"assume_{k}": v for k, v in told.items()}) if told else cfg), report
