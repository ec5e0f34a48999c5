"""Algorithms 2 and 3: diffuse RLS and sliding-window diffuse RLS on AR models of the angles.

Each angle series gets its own AR model (6)-(13), ``alpha_t = c0 + c_1 alpha_{t-1} + ...``;
its parameters come from (14)-(16) (``rls``, forgetting factor lambda) or (17)-(19)
(``window-rls``, window M). The filtered angle is ``H_t theta_t`` and positions follow from
(3)-(5).

Readings of the paper (spec/sea.md):

* Regressors ``H_t`` are past **measured** angles (reading A, the default). Past *filtered*
  angles, as (20) is written, is the option ``regressors="filtered"``; it feeds corrupted
  estimates back into the model.
* The first ``n`` samples have no full regressor and pass through unfiltered.
* Forecasts (20) iterate the AR model with the current ``theta_t`` (future parameters are
  unknown), feeding forecasts back as regressors. There is none for the first ``n`` steps
  (no model yet). Positions ahead follow from the forecast angles by (3)-(5), seen from the
  observer's predicted position; a forecast elevation at or above the horizon has none.
* A track loss (no measurement) coasts: ``theta`` is frozen, the regressor takes the
  one-step forecast, and the estimate is that forecast. A loss within the first n steps
  has no forecast (no model yet): the estimate is NaN there, and a sample whose regressor
  has such a hole passes through unfiltered, as the first n do.

Reading A is computed with the closed forms of :mod:`workbench.estimation.diffuse_rls`
(a test shows they equal the recursions); reading B needs the sequential loop.
"""

from __future__ import annotations

import numpy as np

from workbench.estimation import diffuse_rls as drls
from workbench.experiments.sea import geometry
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate, from_angles
from workbench.experiments.sea.scenario import SeaData


def estimate(data: SeaData, cfg: SeaConfig, windowed: bool) -> Estimate:
    """Run algorithm 2 (``windowed=False``) or 3 on both angles; positions by (3)-(5)."""
    alpha, fa = filter_angle(data.alpha_meas, cfg.order_alpha, cfg, windowed)
    beta, fb = filter_angle(data.beta_meas, cfg.order_beta, cfg, windowed)
    L = cfg.horizon
    T = data.steps
    # the observer's own motion is known: its position l steps ahead from the measured one
    ahead = np.arange(1, L + 1) * data.dt
    obs = data.observer_meas[:, None, :] + ahead[None, :, None] * data.observer_velocity[:, None, :]
    course = np.broadcast_to(data.course[:, None], (T, L))
    forecast, _ = geometry.position(fa, fb, obs, course, data.height)
    name = "window-rls" if windowed else "rls"
    return from_angles(name, data, alpha, beta, forecast=forecast,
                       forecast_angles=np.stack([fa, fb], axis=-1))


def filter_angle(y: np.ndarray, order: int, cfg: SeaConfig, windowed: bool):
    """Filtered angle ``(T,)`` and forecasts ``(T, horizon)`` for one measured angle series.

    The first ``order`` steps pass through unfiltered and have no forecast (NaN).
    """
    if cfg.regressors == "filtered":
        est, theta, series = _sequential(y, order, cfg, windowed)
    else:
        est, theta, series = _closed(y, order, cfg, windowed)
    ahead = forecast(series, theta, order, cfg.intercept, cfg.horizon)
    ahead[:order] = np.nan
    return est, ahead


def _fit(H: np.ndarray, y: np.ndarray, cfg: SeaConfig, windowed: bool) -> np.ndarray:
    if windowed:
        return drls.window_rls_closed(H, y, cfg.window)
    return drls.rls_closed(H, y, cfg.lam)


def _closed(y: np.ndarray, order: int, cfg: SeaConfig, windowed: bool):
    """Reading A with gaps: fit up to each gap, fill the gap by forecasting, go on."""
    T = len(y)
    seen = np.isfinite(y)
    series = y.copy()          # measured where seen, one-step forecasts where not
    theta = np.zeros((T, order + int(cfg.intercept)))
    start = 0
    for g0, g1 in _gaps(seen):
        H = drls.regressors(series[:g0], order, cfg.intercept)
        theta[:g0] = _fit(H, series[:g0], cfg, windowed)
        keep = theta[g0 - 1] if g0 > 0 else theta[0]
        for t in range(g0, g1):
            theta[t] = keep
            series[t] = _one_step(series, t, keep, order, cfg.intercept)
        start = g1
    H = drls.regressors(series, order, cfg.intercept)
    theta_all = _fit(H, np.where(seen, series, np.nan), cfg, windowed)
    theta[start:] = theta_all[start:]
    est = np.einsum("tp,tp->t", np.nan_to_num(H), theta)
    est[:order] = y[:order]                 # the first n samples pass through unfiltered
    # so does a sample whose regressor has a hole (a gap so early that it has no forecast)
    nohist = ~np.all(np.isfinite(H), axis=1) & seen
    est[nohist] = y[nohist]
    est[~seen] = series[~seen]              # coasting: the forecast (NaN where there is none)
    return est, theta, series


def _sequential(y: np.ndarray, order: int, cfg: SeaConfig, windowed: bool):
    """Reading B: regressors are past *filtered* angles, so each step waits for the last."""
    T = len(y)
    p = order + int(cfg.intercept)
    est = np.full(T, np.nan)
    theta = np.zeros((T, p))
    th = np.zeros(p)
    W = np.zeros((p, p))
    rows: list[tuple[np.ndarray, float]] = []
    for t in range(T):
        if t < order:
            est[t] = y[t]
            theta[t] = th
            continue
        h = est[t - order:t][::-1]
        h = np.concatenate([[1.0], h]) if cfg.intercept else h
        if np.isfinite(y[t]) and np.all(np.isfinite(h)):
            if windowed:
                rows.append((h, y[t]))
                rows = rows[-cfg.window:]
                th = np.zeros(p)
                Ww = np.zeros((p, p))
                for hs, ys in rows:
                    Ww += np.outer(hs, hs)
                    th = th + np.linalg.pinv(Ww, rtol=drls.RTOL) @ hs * (ys - hs @ th)
            else:
                W = cfg.lam * W + np.outer(h, h)
                th = th + np.linalg.pinv(W, rtol=drls.RTOL) @ h * (y[t] - h @ th)
            est[t] = h @ th
        elif np.isfinite(y[t]):              # a regressor with a hole: pass through, as the first n
            W = cfg.lam * W
            est[t] = y[t]
        else:
            W = cfg.lam * W
            est[t] = h @ th if np.all(np.isfinite(h)) else np.nan
        theta[t] = th
    return est, theta, est.copy()


def _one_step(series: np.ndarray, t: int, theta: np.ndarray, order: int, intercept: bool) -> float:
    h = series[t - order:t][::-1] if t >= order else np.full(order, np.nan)
    if intercept:
        h = np.concatenate([[1.0], h])
    return float(h @ theta)


def forecast(series: np.ndarray, theta: np.ndarray, order: int, intercept: bool,
             horizon: int) -> np.ndarray:
    """Forecasts (20): ``out[t, l-1]`` is the angle predicted at step t for step t + l.

    Iterates ``y_{t+l} = theta_t . (1?, y_{t+l-1}, ..., y_{t+l-n})`` with forecasts fed back,
    vectorised over t.
    """
    T = len(series)
    # history[t] = (y_t, y_{t-1}, ..., y_{t-n+1}): the regressor for step t + 1
    hist = np.full((T, order), np.nan)
    for i in range(order):
        hist[i:, i] = series[: T - i]
    out = np.empty((T, horizon))
    for step in range(horizon):
        h = np.concatenate([np.ones((T, 1)), hist], axis=1) if intercept else hist
        nxt = np.einsum("tp,tp->t", h, theta)
        out[:, step] = nxt
        hist = np.concatenate([nxt[:, None], hist[:, :-1]], axis=1)
    return out


def _gaps(seen: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index ranges ``[g0, g1)`` where ``seen`` is False."""
    edges = np.diff(np.concatenate([[1], seen.astype(int), [1]]))
    return list(zip(np.flatnonzero(edges == -1), np.flatnonzero(edges == 1), strict=True))
