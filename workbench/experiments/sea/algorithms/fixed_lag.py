"""A fixed-lag smoother of the sea target: GTSAM's ``IncrementalFixedLagSmoother`` on the
same factors as ``gtsam`` and ``isam2`` (:mod:`.smoother`), registered as the plugin
``sea.fixed-lag`` (an entry point, as a user's package would register one).

It runs online: each step's position, velocity and factors join the window, and whatever is
older than the lag is marginalised into a prior on what remains. Step k's estimate is read
when it is about to leave the window, ``lag`` seconds later: it has seen the data up to
``t_k + lag`` and no further (a causal system with a fixed delay), so its accuracy lies
between the causal ``isam2`` (lag 0: the newest step) and the batch ``gtsam`` (lag: the whole
run); the last ``lag`` seconds are read at the end. Its covariance is the joint marginal of
``P(k), V(k)`` at the same moment, so its NEES is over the same 4 states as the EKF's. The
camera's offset it adds is the one the fixes up to the same moment give (:mod:`.observer`).

The lag (``LAG``, 5 s) is a method, not a fit: about the time the elevation's range needs to
become observable on the paper's geometry (the EKF's radial bias fades over ~40 s; 5 s of
future bearings at 0.1 s take most of the early transient out while keeping the delay short).
Another lag: ``workbench.run("sea", estimators=["+fixed-lag", fixed_lag.with_lag(10.0)])``.
"""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import P, V

from workbench.core.estimator import RunContext, estimator
from workbench.experiments.sea import observer
from workbench.experiments.sea.algorithms import smoother
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData

LAG = 5.0
"""Seconds of data after a step that its estimate waits for."""


def run(data: SeaData, cfg: SeaConfig, lag: float = LAG, factors: smoother.FactorSet | None = None,
        name: str = "fixed-lag") -> Estimate:
    """Smooth the run online with a window of ``lag`` seconds; each step read at ``t + lag``."""
    T, dt = data.steps, data.dt
    n = max(0, int(round(lag / dt)))        # steps kept after the one read
    factors = factors or smoother.FactorSet(data, cfg)
    # a lag of (n + 1/2) steps: exactly steps k - n .. k stay in the window at step k
    fls = gtsam.IncrementalFixedLagSmoother((n + 0.5) * dt, smoother.isam2_params())
    X, Vel = np.full((T, 2), np.nan), np.full((T, 2), np.nan)
    cov, state_cov = np.full((T, 2, 2), np.nan), np.full((T, 4, 4), np.nan)
    pos0, _ = factors.initial
    p = v = None
    first = None

    def read(j: int) -> None:
        X[j] = fls.calculateEstimatePoint3(P(j))[:2]
        Vel[j] = fls.calculateEstimatePoint3(V(j))[:2]
        joint = fls.getISAM2().jointMarginalCovariance(gtsam.KeyVector([P(j), V(j)])).fullMatrix()
        keep = [0, 1, 3, 4]                  # x, y of the position and of the velocity
        state_cov[j] = joint[np.ix_(keep, keep)]
        cov[j] = state_cov[j][:2, :2]

    for k in range(T):
        new = smoother.step(data, cfg, factors, k, first is not None, pos0, p, v)
        if new is None:
            continue
        first = k if first is None else first
        fls.update(*new, {P(k): k * dt, V(k): k * dt})
        p, v = fls.calculateEstimatePoint3(P(k)), fls.calculateEstimatePoint3(V(k))
        if k - n >= first:
            read(k - n)
    if first is not None:
        for j in range(max(first, T - n), T):
            read(j)
    # step j is read at step j + n (the last n at the end): it has seen the fixes up to there
    upto = np.minimum(np.arange(T) + n, T - 1)
    return observer.relative(name, data, factors.observer, X, upto, velocity=Vel, covariance=cov,
                             state_cov=state_cov)


def with_lag(lag: float):
    """The fixed-lag smoother with another lag, as an estimator function (for the API)."""

    @estimator(name=f"fixed-lag-{lag:g}s", description=f"GTSAM fixed-lag smoother, each step read {lag:g} s later",
               causal=True, covariances=True, lag=lag)
    def fixed_lag_at(data: SeaData, cfg: SeaConfig, ctx: RunContext) -> Estimate:
        return run(data, cfg, lag, ctx.shared("factors", lambda: smoother.FactorSet(data, cfg)))

    return fixed_lag_at


@estimator(description=f"GTSAM IncrementalFixedLagSmoother, each step read {LAG:g} s later (online, fixed delay)",
           causal=True, covariances=True, lag=LAG)
def fixed_lag(data: SeaData, cfg: SeaConfig, ctx: RunContext) -> Estimate:
    """The fixed-lag smoother on the run's shared factors (the ``gtsam``/``isam2`` ones)."""
    return run(data, cfg, LAG, ctx.shared("factors", lambda: smoother.FactorSet(data, cfg)))
