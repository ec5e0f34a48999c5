"""Diffuse recursive least squares on autoregressive models (Skorohod 2017; sea paper (14)-(19)).

The sea paper models each angle as a non-stationary AR process (6)-(13),
``y_t = c0 + c_1 y_{t-1} + ... + c_n y_{t-n}``, and estimates its parameters with

* diffuse RLS (14)-(16): ``theta_t = theta_{t-1} + K_t (y_t - H_t theta_{t-1})``,
  ``W_t = lambda W_{t-1} + H_t' H_t``, ``W_0 = 0``, ``K_t = W_t^+ H_t'``, ``theta_0 = 0``;
* sliding-window diffuse RLS (17)-(19): the same recursion restarted from ``W = 0`` over the
  last ``M`` samples at every step.

With ``W_0 = 0`` and the pseudo-inverse, the recursion keeps ``W_t theta_t = b_t`` with
``b_t = sum_k lambda^(t-k) H_k' y_k`` and ``theta_t`` in the range of ``W_t``, so
``theta_t = W_t^+ b_t``: the minimum-norm weighted least-squares solution. The closed forms
below use that identity (vectorised over time); the literal recursions are kept as the
reference, and a test shows both agree.

Missing samples (a track loss) carry no row: at such a step the recursion does
``W_t = lambda W_{t-1}``, ``theta_t = theta_{t-1}``, which preserves the identity.
"""

from __future__ import annotations

import numpy as np

RTOL = 1e-10
"""Relative cut-off of the pseudo-inverses. The closed forms build W from differences of
running sums, whose rounding (about 1e-15 of the sums) must not pass for rank: the sea
experiment's windows have condition numbers of 1e3 to 1e6, far inside this cut-off."""


def regressors(series: np.ndarray, order: int, intercept: bool) -> np.ndarray:
    """AR regressor rows ``H_t = (1?, s_{t-1}, ..., s_{t-order})``; NaN for ``t < order``."""
    T = len(series)
    cols = [np.full(T, np.nan) for _ in range(order)]
    for i in range(1, order + 1):
        cols[i - 1][i:] = series[:-i] if i < T else []
    H = np.stack(cols, axis=1) if order else np.empty((T, 0))
    if intercept:
        H = np.concatenate([np.ones((T, 1)), H], axis=1)
    return H


def rls_recursive(H: np.ndarray, y: np.ndarray, lam: float = 1.0, rows: np.ndarray | None = None):
    """Literal diffuse RLS (14)-(16). Returns ``theta`` of shape ``(T, p)``.

    ``rows[t]`` False (or a NaN in ``H_t`` or ``y_t``) means step t has no row.
    """
    T, p = H.shape
    use = _rows(H, y, rows)
    theta = np.zeros(p)
    W = np.zeros((p, p))
    out = np.zeros((T, p))
    for t in range(T):
        W = lam * W
        if use[t]:
            h = H[t]
            W = W + np.outer(h, h)
            theta = theta + np.linalg.pinv(W, rtol=RTOL) @ h * (y[t] - h @ theta)
        out[t] = theta
    return out


def window_rls_recursive(H: np.ndarray, y: np.ndarray, window: int, rows: np.ndarray | None = None):
    """Literal sliding-window diffuse RLS (17)-(19): restart from W = 0 over the last ``window`` steps.

    The window at step t holds steps ``t-window+1 .. t`` (fewer at the start). A window with
    no row keeps the previous estimate (the filter coasts).
    """
    T, p = H.shape
    use = _rows(H, y, rows)
    out = np.zeros((T, p))
    prev = np.zeros(p)
    for t in range(T):
        lo = max(0, t - window + 1)
        if not use[lo : t + 1].any():
            out[t] = prev
            continue
        theta = np.zeros(p)
        W = np.zeros((p, p))
        for s in range(lo, t + 1):
            if use[s]:
                h = H[s]
                W = W + np.outer(h, h)
                theta = theta + np.linalg.pinv(W, rtol=RTOL) @ h * (y[s] - h @ theta)
        out[t] = prev = theta
    return out


def rls_closed(H: np.ndarray, y: np.ndarray, lam: float = 1.0, rows: np.ndarray | None = None):
    """Closed form of (14)-(16): ``theta_t = W_t^+ b_t`` with exponentially weighted sums."""
    outer, rhs = _products(H, y, rows)
    if lam == 1.0:
        W = np.cumsum(outer, axis=0)
        b = np.cumsum(rhs, axis=0)
    else:
        from scipy.signal import lfilter  # imported here: scipy.signal costs ~1 s at start-up

        W = lfilter([1.0], [1.0, -lam], outer, axis=0)
        b = lfilter([1.0], [1.0, -lam], rhs, axis=0)
    return _solve(W, b)


def window_rls_closed(H: np.ndarray, y: np.ndarray, window: int, rows: np.ndarray | None = None):
    """Closed form of (17)-(19): ``theta_t = W^+ b`` over the window, by differences of cumsums.

    A window with no row keeps the previous estimate, as the recursion does.
    """
    outer, rhs = _products(H, y, rows)
    cw = np.cumsum(outer, axis=0)
    cb = np.cumsum(rhs, axis=0)
    W = cw.copy()
    b = cb.copy()
    W[window:] -= cw[:-window]
    b[window:] -= cb[:-window]
    count = np.cumsum(_rows(H, y, rows).astype(int))
    count[window:] -= count[:-window].copy()
    theta = _solve(W, b)
    empty = np.flatnonzero(count == 0)
    for t in empty:  # coast: keep the previous estimate
        theta[t] = theta[t - 1] if t > 0 else 0.0
    return theta


def _rows(H: np.ndarray, y: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    use = np.isfinite(y) & np.all(np.isfinite(H), axis=1)
    return use if rows is None else use & rows


def _products(H: np.ndarray, y: np.ndarray, rows: np.ndarray | None):
    use = _rows(H, y, rows)
    Hz = np.where(use[:, None], H, 0.0)
    yz = np.where(use, y, 0.0)
    return Hz[:, :, None] * Hz[:, None, :], Hz * yz[:, None]


def _solve(W: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched minimum-norm solutions ``W_t^+ b_t``."""
    return np.einsum("tij,tj->ti", np.linalg.pinv(W, rtol=RTOL, hermitian=True), b)
