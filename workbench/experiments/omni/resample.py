"""Datasets simulated from a run's own answer: the omni side of the parametric bootstrap
(:mod:`workbench.metrics.bootstrap`; Efron and Tibshirani 1993, ch. 6).

The truth of a resample:

* the path: the run's odometry taken as the true controls, integrated from the start (a start with
  a covariance drawn from it), so every step obeys the motion model exactly as the estimators
  model it (the smoother's own path would need controls no model step reproduces);
* the map: each landmark the reference smoother mapped, put where that smoother sees it from its
  pose at the landmark's middle sighting, relative to the new path's pose at that step: the
  geometry each bearing sees (range, side, parallax) is the answer's where the landmark is seen
  most;
* the schedule: every bearing of a mapped landmark at its step, as the data had it (a landmark the
  smoother left out is left out);
* the outliers: each bearing the reference smoother left out at its gate (a misread id, a heavy
  tail) carries its residual at the smoother's answer, as the data had it (:func:`_replayed`), not
  a Gaussian draw: a log with misreads gives resamples with the same misreads, where they were.

The noise: the odometry's (each step's own covariance, or the motion's sigmas) and the bearings'
(each one's sigma) as the estimators were told them (:func:`.run.assumed`), times the factor the
data identify for each group: the reference smoother's variance components
(:mod:`workbench.metrics.diagnosis`), iterated (:func:`factors`), where identified; 1
elsewhere. The resample states the
data's own noise, so the config's assumptions apply to it as they did to the data.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from workbench.errors import WorkbenchError
from workbench.estimation.angles import wrap
from workbench.experiments.omni.evaluate import on_grid
from workbench.experiments.omni.scenario import OmniData
from workbench.metrics import diagnosis, truthfree
from workbench.metrics.bootstrap import ITERATED

FACTOR_RANGE = (0.1, 10.0)
"""An identified noise factor outside this is taken at its end (a run-away variance component)."""
VCE_ROUNDS = 4
"""The reference smoother's solves at most, the run's own included, to iterate its variance components
(each round moves a share of the way, about a third on the paper's simulation; :func:`rest`
extrapolates the rest from the last steps)."""


def reference(result: Any) -> tuple[str, Any]:
    """The run's smoother (:func:`~workbench.metrics.truthfree.smoother`) and its estimate; a
    one-line error where the run has none with a map."""
    name = truthfree.smoother(result.estimators, result.estimates)
    est = result.estimates.get(name) if name else None
    if est is None or est.map_mean is None or not len(est.map_mean):
        raise WorkbenchError("--bootstrap: the run needs a smoother with a map (gtsam-batch or isam2) to simulate from")
    return name, est


def _one_step(est: Any) -> dict[str, float]:
    """One step of variance component estimation from the smoother's residuals (the diagnosis's
    factors, :func:`workbench.metrics.diagnosis.components`, without the rest of its fits):
    ``odometry``, ``bearings`` (1 where not identified, or too few rows to say)."""
    from workbench.experiments.omni.metrics import NOISE_GROUPS

    out = {"odometry": 1.0, "bearings": 1.0}
    ev = diagnosis.evidence(est)
    if ev is None or np.isfinite(ev.q).sum() < diagnosis.MIN_ROWS:
        return out
    for g, v in diagnosis.components(ev, NOISE_GROUPS).items():
        if g in out and diagnosis.identified(v["interval"]):
            out[g] = float(v["factor"])
    return out


def factors(result: Any, cfg: Any) -> dict[str, float]:
    """The noise factors (sigma) on what the estimators were told that the data identify: the
    reference smoother's variance components, iterated (the smoother solved again with each round's
    factors, at most :data:`VCE_ROUNDS` solves in all) while they contract, the rest of the way
    extrapolated (:func:`rest`). One step from a wrong start is pulled toward it (Koch,
    *Parameter Estimation and Hypothesis Testing in Linear Models*, sec. 3.6.3: the estimate is
    unbiased only at the true weights; on the paper's simulation with the odometry assumed 3x too
    wide, one step says 1.5x); the fixed point is the components' maximum likelihood (REML)."""
    name, est = reference(result)
    logs = {g: math.log(v) for g, v in _one_step(est).items()}
    steps = [dict(logs)]
    for _ in range(VCE_ROUNDS - 1):
        if max(abs(v) for v in steps[-1].values()) < math.log(1.05):
            break
        told = dataclasses.replace(
            cfg, assume_odometry_scale=(cfg.assume_odometry_scale or 1.0) * math.exp(logs["odometry"]),
            assume_bearing_scale=(cfg.assume_bearing_scale or 1.0) * math.exp(logs["bearings"]))
        again = result.experiment.estimate(result.data, told, [result.estimators[name]])[0].get(name)
        if again is None:
            break
        step = {g: math.log(v) for g, v in _one_step(again).items()}
        if max(abs(v) for v in step.values()) > 0.9 * max(abs(v) for v in steps[-1].values()):
            break  # not contracting: keep what it had
        steps.append(step)
        logs = {g: logs[g] + step[g] for g in logs}
    for g in logs:
        logs[g] += rest([s[g] for s in steps])
    return {g: float(np.clip(math.exp(v), *FACTOR_RANGE)) for g, v in logs.items()}


def rest(steps: list[float]) -> float:
    """The rest of a converging iteration's sum from its ``steps`` so far (each a step in a log-factor).
    Two steps: Aitken's delta-squared (the ratio ``r`` of the last two, the rest ``b r / (1 - r)``).
    Three or more, where the ratio itself shrinks (``r2 < r1``): the ratios taken to go on shrinking
    by that factor, as variance components do, converging faster as the weights near their fixed
    point (on the paper's simulation with the odometry told 3x too wide the ratios ran 0.66, 0.62,
    0.58, 0.54; Aitken from the fourth solve then read 0.316 and 0.306 where ten solves converge on
    0.333 and 0.323, this 0.333 and 0.323). None (0) where the steps do not contract."""
    if len(steps) < 2 or not steps[-2]:
        return 0.0
    b, r = steps[-1], steps[-1] / steps[-2]
    if not 0.0 < r < 0.9:
        return 0.0
    q = r / (steps[-2] / steps[-3]) if len(steps) >= 3 and steps[-3] else 1.0
    if not 0.0 < q < 1.0:
        return b * r / (1.0 - r)
    total, term = 0.0, b
    for _ in range(200):
        r *= q
        term *= r
        total += term
        if abs(term) < 1e-12:
            break
    return total


def _path(data: OmniData, told: OmniData, k: float, rng: np.random.Generator
          ) -> tuple[np.ndarray, np.ndarray]:
    """The true path (the odometry as the true controls) and the odometry measured along it, its
    noise the told one times ``k``."""
    m = told.motion
    dt = np.diff(data.t)
    start = np.asarray(data.start, float).copy()
    if np.any(data.start_cov):
        start = start + rng.multivariate_normal(np.zeros(3), np.asarray(data.start_cov, float))
    truth = m.integrate(start, data.controls, dt)
    if np.any(m.sigma_q):  # the process noise Q is the path's own: step by step
        q = rng.normal(size=(len(dt), 3)) * np.asarray(m.sigma_q) * (np.sqrt(dt)[:, None] if m.per_second else 1.0)
        pose = start.copy()
        for i in range(len(dt)):
            pose = m.integrate(pose, data.controls[i:i + 1], dt[i:i + 1])[1] + k * q[i]
            truth[i + 1] = pose
        truth[:, 2] = wrap(truth[:, 2])
    n_u = data.controls.shape[1]
    if m.model == "increments":
        cov = np.broadcast_to(np.diag(np.square(m.sigma_u)), (len(dt), 3, 3)).copy()
        if told.control_var is not None:
            cv = np.asarray(told.control_var, float)
            own = np.isfinite(cv).all(axis=(1, 2))
            cov[own] = cv[own]
    else:
        var = np.square(np.asarray(m.sigma_u, float))[None, :] * np.ones((len(dt), n_u))
        if m.per_second:
            with np.errstate(divide="ignore"):
                var = var / np.where(dt > 0, dt, np.inf)[:, None]
        if told.control_var is not None:
            var = var + np.nan_to_num(np.asarray(told.control_var, float))
        cov = var[:, :, None] * np.eye(n_u)
    chol = np.linalg.cholesky(cov + 1e-18 * np.eye(n_u))
    noisy = data.controls + k * np.einsum("kij,kj->ki", chol, rng.normal(size=(len(dt), n_u)))
    return truth, noisy


def _replayed(data: OmniData, est: Any, ref: np.ndarray, at: dict[int, int], final: np.ndarray,
              idx: np.ndarray) -> np.ndarray:
    """For the bearings ``idx`` (the dataset's) the reference smoother left out at its gate, each
    one's residual at the smoother's answer (rad; NaN for the rest, and where its step has no
    smoothed pose): the outliers' part of the resample's noise, replayed where the data had it (the
    residual bootstrap, Efron and Tibshirani 1993, sec. 9.5, for what the Gaussian does not hold)."""
    out = np.full(len(idx), np.nan)
    gated = getattr(est, "gated_bearings", None)
    if gated is None or not len(gated):
        return out
    j = np.flatnonzero(np.isin(idx, np.asarray(gated, int)))
    i = idx[j]
    row = np.array([at.get(int(s), -1) for s in data.meas_step[i]], int)
    p = np.where((row >= 0)[:, None], ref[np.maximum(row, 0)], np.nan)
    d = final[np.asarray(data.meas_lm, int)[i]] - p[:, :2]
    out[j] = wrap(np.asarray(data.meas_bearing, float)[i] - (np.arctan2(d[:, 1], d[:, 0]) - p[:, 2]))
    return out


def resample(result: Any, cfg: Any, rng: np.random.Generator) -> OmniData:
    """One dataset simulated from the run's answer (the module's text)."""
    from workbench.experiments.omni.run import assumed

    data: OmniData = result.data
    if getattr(cfg, "from_images", False):
        raise WorkbenchError("--bootstrap: bearings from images cannot be resampled (their noise is the image stage's)")
    _, est = reference(result)
    k = result.shared(ITERATED, lambda: factors(result, cfg))  # the diagnosis gives them beside its one step
    told = assumed(data, cfg)
    truth, noisy = _path(data, told, k["odometry"], rng)
    pose = est.smoothed if getattr(est, "smoothed", None) is not None else est.pose
    ref = on_grid(dataclasses.replace(est, pose=pose), data.grid)[0] if est.steps is not None else None
    if ref is None:
        raise WorkbenchError("--bootstrap: the reference smoother gives no trajectory")
    at = {int(s): i for i, s in enumerate(data.grid)}
    final = np.asarray(est.map_mean[-1], float)
    landmarks = np.full((len(final), 2), np.nan)
    keep = np.zeros(len(data.meas_lm), bool)
    for lm in np.unique(data.meas_lm):
        if lm >= len(final) or not np.isfinite(final[lm]).all():
            continue
        idx = np.flatnonzero(data.meas_lm == lm)
        steps = [int(s) for s in data.meas_step[idx] if int(s) in at and np.isfinite(ref[at[int(s)]]).all()]
        if not steps:
            continue
        s = steps[len(steps) // 2]
        p = ref[at[s]]
        c, sn = math.cos(p[2]), math.sin(p[2])
        d = final[lm] - p[:2]
        rel = np.array([c * d[0] + sn * d[1], -sn * d[0] + c * d[1]])
        q = truth[s]
        c, sn = math.cos(q[2]), math.sin(q[2])
        landmarks[lm] = q[:2] + [c * rel[0] - sn * rel[1], sn * rel[0] + c * rel[1]]
        keep[idx] = True
    ms, ml = data.meas_step[keep], data.meas_lm[keep]
    p, q = truth[ms], landmarks[ml]
    clean = np.arctan2(q[:, 1] - p[:, 1], q[:, 0] - p[:, 0]) - p[:, 2]
    sigma = told.bearing_sigma(np.flatnonzero(keep)) * k["bearings"]
    noise = sigma * rng.normal(size=len(clean))
    replayed = _replayed(data, est, ref, at, final, np.flatnonzero(keep))
    bearings = wrap(clean + np.where(np.isfinite(replayed), replayed, noise))
    return dataclasses.replace(
        data, controls=noisy, truth=truth, meas_step=ms, meas_lm=ml, meas_bearing=bearings,
        meas_sigma=None if data.meas_sigma is None else np.asarray(data.meas_sigma, float)[keep],
        landmarks=landmarks, truth_sigma=None,
        label=f"bootstrap of {data.label}", repairs=None)
