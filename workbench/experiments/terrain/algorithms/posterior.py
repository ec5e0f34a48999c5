"""The search's posterior: the winning filter carried past its cell, and the covariances that
cover the cell choice (not in the paper; ``spec/terrain.md``'s search, then a refinement).

The paper's refinement (:attr:`search.SearchResult.refinement`) and the iterated filter
(:func:`search.iterate`) keep the winning cell's prior ``N(m_pq, G)``: they are conditional on
the winner being the true cell. It seldom is: the functional (4) separates the linear cells
well and the angular ones hardly at all (200 x 200 synthetic, common mode, seed 4, 5 runs: the
winner in the true position cell in 60 % of runs, in the true cell in 0 %), so the cell's prior
pulls the angles to a wrong centre with a sigma of a third of a cell, and the covariance
``Gamma_N`` leaves that out (position ANEES 15.7 for the refinement, 8.0 for the iterated filter).

Here the prior is the navigation system's own, ``N(0, diag((sigma_fraction * max)^2))`` (the
cube the hypotheses tile, :func:`navigation.prior_covariance`), so nothing is conditional on
the cell: the winner only says where to start. Two steps:

1. **The effective number of independent nodes.** The functional (4) sums ~16,000 node terms as
   if their residuals were independent with variance ``R``. They are neither: on the real
   frames neighbouring residuals correlate (0.4-0.5 at one pixel; the texture, the
   resampling, the radiometric remainder), on the synthetic pair their variance is ~0.1 ``R``
   (``sigma_r`` = 0.05 against image noise 0.01). The node sum's score ``s_k = H_k r_k / R``
   has the naive information ``H = sum H_k H_k' / R``; its actual variance ``J`` is the
   spatial heteroscedasticity-and-autocorrelation-consistent (HAC) sum over lags of the
   scores' cross-covariances, with Bartlett weights (the product of two triangular kernels:
   positive semi-definite, Newey and West 1987) and the bandwidth of each image axis by
   Andrews' (1991, section 6) plug-in rule for the Bartlett kernel from the residuals' lag-one
   autocorrelation ``rho`` along that axis, ``1.1447 (4 rho^2 / ((1 - rho)^2 (1 + rho)^2) T)^(1/3)``
   with ``T`` nodes along it. Their ratio in the posterior's metric,
   ``kappa = tr(Gamma J Gamma) / tr(Gamma H Gamma)`` (``Gamma = (G^-1 + H)^-1``), is the node
   sum's variance inflation (``kappa = c`` when ``J = c H``: the composite-likelihood magnitude
   adjustment of Ribatet, Cooley and Davison 2012, weighted by the posterior), and
   ``N / kappa`` the effective number of independent nodes.
2. **The tempered posterior.** The likelihood's log is divided by ``kappa`` (the adjustment
   itself) and the posterior's mode found by damped Gauss-Newton (the iterated filter's
   update (2)-(3) re-linearised at its own estimate, a step halved until the cost falls):
   ``C(x) = (x - mu)' G^-1 (x - mu) + sum r_k(x)^2 / (kappa R)``. Its covariance is the
   estimating equation's sandwich (:func:`sandwich`): the score's HAC variance ``J`` between
   the actual sensitivity of the node sum (:func:`bread`) on both sides, not the model's
   ``(G^-1 + H / kappa)^-1``.

The covariance of any other estimate ``x^`` of the same state (the winning cell's refinement,
the iterated filter) is its mean squared error under this posterior,
``Gamma + (x^ - x_post)(x^ - x_post)'``: it covers the distance the cell's prior put between
the estimate and what the data and the navigation system say.

Not a mixture over hypotheses weighted by ``exp(-I_pq / 2)``: with ``I_pq`` a sum over
correlated nodes it collapses onto the winner, and tempered by the measured ``kappa`` it still
does: the runner-up's functional is 5-1560 above the winner's (``kappa`` 0.15-1.9), so the weight
left off the winner is at most 3 % (synthetic 200 x 200, seeds 4, 7, 11, 5 runs in each mode;
both ngi pairs in both modes, 3 runs each), and each hypothesis's state is a one-step
linearisation a third of a cell off (what made the refinement's ANEES 15.7). The posterior's
spread is what is left of the cell choice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.experiments.terrain.algorithms import search
from workbench.experiments.terrain.algorithms.search import Problem


@dataclass
class Posterior:
    """The tempered posterior's mode and covariance (error-state space) and what made them."""

    state: np.ndarray             # (n,) the mode
    covariance: np.ndarray        # (n, n)
    kappa: float                  # the node sum's variance inflation (1: independent nodes with variance R)
    effective_nodes: float        # nodes / kappa
    bandwidth: tuple[float, float]  # Bartlett bandwidths along u and v, nodes
    correlation: tuple[float, float]  # the residuals' lag-one autocorrelation along u and v
    iterations: int

    def mse(self, estimate: np.ndarray) -> np.ndarray:
        """The mean squared error matrix of ``estimate`` under this posterior:
        ``Gamma + (x^ - x_post)(x^ - x_post)'``."""
        d = np.asarray(estimate, float) - self.state
        return self.covariance + np.outer(d, d)


def node_grid(p: Problem) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Each node's column and row on the node lattice (``node_step`` pixels apart) and the
    lattice's width and height."""
    u, v = p.nodes[:, 0], p.nodes[:, 1]
    steps = np.diff(np.unique(np.concatenate([u, v])))
    step = float(steps.min()) if len(steps) else 1.0
    iu = np.rint((u - u.min()) / step).astype(int)
    iv = np.rint((v - v.min()) / step).astype(int)
    return iu, iv, int(iu.max()) + 1, int(iv.max()) + 1


def lag_one(field: np.ndarray, axis: int) -> float:
    """The lag-one autocorrelation of a lattice field (NaN where there is no node) along an
    axis, over the pairs of neighbouring nodes both present."""
    a = np.moveaxis(field, axis, 0)
    x, y = a[:-1], a[1:]
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return 0.0
    den = np.sqrt(np.sum(x[ok] ** 2) * np.sum(y[ok] ** 2))
    return float(np.sum(x[ok] * y[ok]) / den) if den > 0 else 0.0


def andrews_bandwidth(rho: float, length: int) -> float:
    """Andrews' (1991, section 6) AR(1) plug-in bandwidth of the Bartlett kernel for a series of
    ``length`` with lag-one autocorrelation ``rho``; at least 1 (lag 0 alone)."""
    rho = float(np.clip(rho, -0.97, 0.97))
    alpha = 4.0 * rho ** 2 / ((1.0 - rho) ** 2 * (1.0 + rho) ** 2)
    return max(1.0, 1.1447 * (alpha * length) ** (1.0 / 3.0))


def hac(r: np.ndarray, h: np.ndarray, iu: np.ndarray, iv: np.ndarray, shape: tuple[int, int], noise: float
        ) -> tuple[np.ndarray, np.ndarray, tuple[float, float], tuple[float, float]]:
    """Residuals ``r (N,)`` and measurement rows ``h (n, N)`` of nodes at lattice column ``iu``,
    row ``iv`` (lattice ``shape = (rows, cols)``), noise variance ``R``: the naive information
    ``H = sum h_k h_k' / R`` and the HAC variance ``J`` of the score ``sum h_k r_k / R``
    (Bartlett weights, Andrews' bandwidth per axis from the residuals' lag-one
    autocorrelation), the bandwidths and the autocorrelations, along u then v."""
    gv, gu = shape
    field = np.full((gv, gu), np.nan)
    field[iv, iu] = r - r.mean()
    rho = (lag_one(field, 1), lag_one(field, 0))
    band = (andrews_bandwidth(rho[0], gu), andrews_bandwidth(rho[1], gv))
    s = h * (r / noise)[None]
    s = s - s.mean(axis=1, keepdims=True)
    padded = (2 * gv, 2 * gu)                         # zero-padded: the correlations do not wrap
    lattice = np.zeros((len(s), *padded))
    lattice[:, iv, iu] = s
    f = np.fft.rfft2(lattice)
    du = np.abs(np.fft.fftfreq(padded[1], 1.0 / padded[1]))
    dv = np.abs(np.fft.fftfreq(padded[0], 1.0 / padded[0]))
    w = np.clip(1.0 - dv / band[1], 0.0, None)[:, None] * np.clip(1.0 - du / band[0], 0.0, None)[None]
    keep = w > 0
    n = len(s)
    j = np.empty((n, n))
    for a in range(n):
        for b in range(a, n):
            c = np.fft.irfft2(f[a] * np.conj(f[b]), s=padded)
            j[a, b] = j[b, a] = float(np.sum(c[keep] * w[keep]))
    return h @ h.T / noise, j, band, rho


def score_variance(p: Problem, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[float, float],
                                                             tuple[float, float]]:
    """:func:`hac` of the problem's nodes at ``state`` (their residuals and rows by the
    compiled kernel, :func:`search.rows`)."""
    r0, h = search.rows(p, np.asarray(state, float)[None])
    iu, iv, gu, gv = node_grid(p)
    return hac(r0[0], h[0], iu, iv, (gv, gu), p.r)


def inflation(p: Problem, state: np.ndarray, prior: np.ndarray) -> tuple[float, tuple[float, float],
                                                                         tuple[float, float]]:
    """``kappa = tr(Gamma J Gamma) / tr(Gamma H Gamma)``, ``Gamma = (G^-1 + H)^-1``: the node
    sum's variance inflation at ``state`` (module docstring, step 1), with the bandwidths and
    the residuals' lag-one autocorrelations."""
    hh, j, band, rho = score_variance(p, state)
    gam = np.linalg.inv(np.linalg.inv(prior) + hh)
    kappa = float(np.trace(gam @ j @ gam) / np.trace(gam @ hh @ gam))
    return kappa, band, rho


def tempered_mode(p: Problem, mean: np.ndarray, prior: np.ndarray, start: np.ndarray, kappa: float,
                  iterations: int = 30, tol: float = 1e-3) -> tuple[np.ndarray, np.ndarray, int]:
    """Damped Gauss-Newton on ``C(x) = (x - mean)' G^-1 (x - mean) + sum r_k(x)^2 / (kappa R)``
    (module docstring, step 2): each step the iterated filter's update (2)-(3) re-linearised at
    ``x``, halved until ``C`` falls; stops when a step moves every component less than ``tol``
    of its prior sigma. Returns the mode, ``(G^-1 + H(x) / (kappa R))^-1`` there, the steps taken."""
    ginv = np.linalg.inv(prior)
    sigma = np.sqrt(np.diag(prior))
    scale = 1.0 / (kappa * p.r)

    def cost(x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        hh, hr, rr = search.sums(p, x[None])
        d = x - mean
        return float(rr[0] * scale + d @ ginv @ d), hh[0], hr[0]

    x = np.array(start, float)
    c, hh, hr = cost(x)
    taken = 0
    while taken < iterations:
        taken += 1
        gam = np.linalg.inv(ginv + hh * scale)
        step = gam @ (hr * scale - ginv @ (x - mean))
        lam = 1.0
        while True:
            new = x + lam * step
            c_new, hh_new, hr_new = cost(new)
            if c_new <= c or lam < 1e-3:
                break
            lam *= 0.5
        x, c, hh, hr = new, c_new, hh_new, hr_new
        if np.all(np.abs(lam * step) < tol * sigma):
            break
    gam = np.linalg.inv(ginv + hh * scale)
    return x, 0.5 * (gam + gam.T), taken


def bread(p: Problem, state: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """``-d(sum H_k r_k / R)/dx`` at ``state`` by central differences of the compiled kernel's node
    sums, ``steps`` per component: the node sum's actual sensitivity. The model's ``H = sum H_k
    H_k' / R`` understates it (image II's gradient by central differences, read bilinearly, is
    smoother than the bilinear read itself; :mod:`.bounds`): 1.12-1.35 times ``H`` along every
    eigen-direction on the 200 x 200 synthetic pairs (common mode, seed 4)."""
    x = np.asarray(state, float)
    n = len(x)
    out = np.empty((n, n))
    for i in range(n):
        d = np.zeros(n)
        d[i] = steps[i]
        plus = search.sums(p, (x + d)[None])[1][0]
        minus = search.sums(p, (x - d)[None])[1][0]
        out[:, i] = -(plus - minus) / (2.0 * steps[i] * p.r)
    return 0.5 * (out + out.T)


def sandwich(p: Problem, state: np.ndarray, prior: np.ndarray, kappa: float) -> np.ndarray:
    """The covariance of the tempered mode (Godambe's sandwich): it solves
    ``psi(x) = G^-1 x - sum H_k(x) r_k(x) / (kappa R) = 0``, so linearised about the truth its error
    is ``-Psi^-1 psi(x_true)`` with ``Psi = G^-1 + B / kappa`` (:func:`bread`) and
    ``Var psi(x_true) = G^-1 + J / kappa^2`` (the prior's spread and the score's HAC variance,
    :func:`score_variance`); ``Psi^-1 (G^-1 + J / kappa^2) Psi^-T``. The bread's steps are the
    model's own posterior sigmas (halved, the synthetic runs' ANEES moves under 1 %, the real
    pairs' up to 13 %)."""
    ginv = np.linalg.inv(prior)
    hh, j, _, _ = score_variance(p, state)
    model = np.linalg.inv(ginv + hh / kappa)
    psi = np.linalg.inv(ginv + bread(p, state, np.sqrt(np.diag(model))) / kappa)
    cov = psi @ (ginv + j / kappa ** 2) @ psi.T
    return 0.5 * (cov + cov.T)


def posterior(p: Problem, prior: np.ndarray, start: np.ndarray) -> Posterior:
    """The tempered posterior under the navigation prior ``N(0, prior)`` from ``start`` (the
    winning filter iterated in its cell): ``kappa`` at ``start``, the mode, its sandwich
    covariance."""
    kappa, band, rho = inflation(p, start, prior)
    state, _, its = tempered_mode(p, np.zeros_like(start), prior, start, kappa)
    return Posterior(state, sandwich(p, state, prior, kappa), kappa, len(p.nodes) / kappa, band, rho, its)
