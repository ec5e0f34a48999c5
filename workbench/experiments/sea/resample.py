"""Datasets simulated from a run's own answer: the sea side of the parametric bootstrap
(:mod:`workbench.metrics.bootstrap`; Efron and Tibshirani 1993, ch. 6).

The truth of a resample:

* the object: a nearly-constant-velocity track (the estimators' model, :func:`.scenario.
  simulate_target`) from the run's smoother's state at the first step it holds one, its
  acceleration noise the one the estimators were told times the factor the data identify;
* the camera: where the fixes put it, the known velocity's path ``d_k`` plus the fixes' mean
  offset (:mod:`.observer`), or the fixes themselves where the velocity is not known; its fixes
  that path with the told noise;
* the angles (1)-(2) from that camera to that object at the steps the data saw it, with the told
  noise times the identified factor; no impulse.

The factors: the noise the EKF's likelihood of the run's data finds (:func:`factors`), over the
told noise, where it identifies it (1 elsewhere). The resample states the data's own noise, so the
config's assumptions apply to it as they did to the data.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from workbench.errors import WorkbenchError
from workbench.experiments.sea import geometry
from workbench.experiments.sea.scenario import SeaData
from workbench.metrics import truthfree

FACTOR_RANGE = (0.1, 10.0)
"""An identified noise factor outside this is taken at its end."""


def factors(result: Any) -> dict[str, float]:
    """The noise factors (sigma) on what the estimators were told that the data identify: the
    maximum of the EKF's likelihood of the run's data (:func:`workbench.core.likelihood.
    maximum_likelihood`), each value over the told one where identified, 1 where not; the angles'
    the geometric mean of the two angles'.

    Not the EKF's one-step split of its innovations (the diagnosis's): an innovation is mostly the
    angles' noise, and the split read the acceleration x0.7 whether the filter was told 0.3, 1 or
    3 times the data's (10 runs of the paper's simulation each), while the likelihood, the filter
    run again at each value, finds it from 0.3x (0.094 against the 0.1 that made the data)."""
    from workbench.core import likelihood

    out = {"acceleration": 1.0, "angles": 1.0}
    exp, cfg = result.experiment, result.config
    if exp is None or cfg is None or exp.parts.tunable is None:
        return out
    found = likelihood.maximum_likelihood(exp, result.data, cfg)
    ratio = {n: v / told for n, (told, v, ok) in found.items() if ok and told > 0}
    if "sigma_acc" in ratio:
        out["acceleration"] = float(np.clip(ratio["sigma_acc"], *FACTOR_RANGE))
    angles = [ratio[n] for n in ("sigma_alpha_arcmin", "sigma_beta_arcmin") if n in ratio]
    if angles:
        out["angles"] = float(np.clip(np.exp(np.mean(np.log(angles))), *FACTOR_RANGE))
    return out


def _track(x0: np.ndarray, i0: int, w: np.ndarray, dt: float) -> np.ndarray:
    """The nearly-constant-velocity track ``(T, 4)`` through state ``x0`` at step ``i0`` driven by the
    accelerations ``w (T-1, 2)`` (:func:`.scenario.simulate_target`'s recursion), forwards from it and
    backwards to it, by cumulative sums."""
    T = len(w) + 1
    vel, pos = np.empty((T, 2)), np.empty((T, 2))
    vel[i0], pos[i0] = x0[2:], x0[:2]
    ahead = w[i0:]
    vel[i0 + 1:] = x0[2:] + dt * np.cumsum(ahead, axis=0)
    pos[i0 + 1:] = x0[:2] + np.cumsum(dt * vel[i0:-1] + dt ** 2 / 2.0 * ahead, axis=0)
    behind = w[:i0][::-1]  # w[i0-1], w[i0-2], ...
    vel[:i0] = (x0[2:] - dt * np.cumsum(behind, axis=0))[::-1]
    pos[:i0] = (x0[:2] - np.cumsum(dt * vel[:i0][::-1] + dt ** 2 / 2.0 * behind, axis=0))[::-1]
    return np.concatenate([pos, vel], axis=1)


def _camera(data: SeaData) -> np.ndarray:
    """The camera's path as the fixes give it: the known velocity's path plus their mean offset."""
    if not data.velocity_known:
        return np.asarray(data.observer_meas, float).copy()
    v = np.asarray(data.observer_velocity, float)
    d = np.concatenate([np.zeros((1, 2)), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(data.t)[:, None], axis=0)])
    return d + np.nanmean(np.asarray(data.observer_meas, float) - d, axis=0)


def resample(result: Any, cfg: Any, rng: np.random.Generator) -> SeaData:
    """One dataset simulated from the run's answer (the module's text)."""
    from workbench.experiments.sea.run import assumed

    data: SeaData = result.data
    if getattr(cfg, "from_images", False):
        raise WorkbenchError("--bootstrap: angles from images cannot be resampled (their noise is the image stage's)")
    name = truthfree.smoother(result.estimators, result.estimates)
    est = result.estimates.get(name) if name else None
    if est is None or est.velocity is None:
        raise WorkbenchError("--bootstrap: the run needs a smoother with velocities (gtsam) to simulate from")
    state = np.concatenate([est.position, est.velocity], axis=1)
    first = np.flatnonzero(np.isfinite(state).all(axis=1))
    if not len(first):
        raise WorkbenchError("--bootstrap: the run's smoother holds no state to simulate from")
    k = result.shared("bootstrap factors", lambda: factors(result))
    told = assumed(data, cfg)
    T, dt, i0 = data.steps, data.dt, int(first[0])
    w = rng.normal(0.0, told.sigma_acc * k["acceleration"], size=(T - 1, 2))
    target = _track(state[i0], i0, w, dt)
    camera = _camera(data)
    alpha, beta = geometry.angles(target[:, :2], camera, data.course, data.height)
    seen = np.asarray(data.seen, bool)
    am = np.where(seen, alpha + rng.normal(0.0, told.sigma_alpha * k["angles"], T), np.nan)
    bm = np.where(seen, beta + rng.normal(0.0, told.sigma_beta * k["angles"], T), np.nan)
    fixes = camera + rng.normal(0.0, told.sigma_observer, (T, 2))
    return dataclasses.replace(data, observer=camera, observer_meas=fixes, target=target, alpha=alpha, beta=beta,
                               alpha_meas=am, beta_meas=bm, disturbed=np.zeros(T, bool), impulse=None,
                               label=f"bootstrap of {data.label}", repairs=None)
