"""The sea experiment's estimator table: name -> how to run it, colour, what it is.

Each runner is ``(data, cfg[, ctx]) -> Estimate`` and imports its module when first run, so the
table costs nothing to read. Adding a built-in is one module with such a function and one row
here naming it; a researcher's own goes beside these
without touching the package (:mod:`workbench.core.estimator`).
"""

from __future__ import annotations

from workbench.core.estimator import Estimator, RunContext, table
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.scenario import SeaData


def geometric(data: SeaData, cfg: SeaConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.sea.algorithms import geometric

    return geometric.estimate(data)


def rls(data: SeaData, cfg: SeaConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.sea.algorithms import ar_filter

    return ar_filter.estimate(data, cfg, windowed=False)


def window_rls(data: SeaData, cfg: SeaConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.sea.algorithms import ar_filter

    return ar_filter.estimate(data, cfg, windowed=True)


def ekf(data: SeaData, cfg: SeaConfig) -> Estimate:
    from workbench.experiments.sea.algorithms import ekf

    return ekf.estimate(data, cfg)


def factors(data: SeaData, cfg: SeaConfig, ctx: RunContext):
    """The run's GTSAM factors, built once for every graph estimator (same data, same graph)."""
    from workbench.experiments.sea.algorithms import smoother

    return ctx.shared("factors", lambda: smoother.FactorSet(data, cfg))


def gtsam_batch(data: SeaData, cfg: SeaConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.sea.algorithms import smoother

    # its covariances in every run (+0.03 s a run): the causal estimators' truth-free disagreement
    # with it is a test over all the runs, not run 0's alone
    return smoother.batch(data, cfg, True, factors(data, cfg, ctx))


def isam2(data: SeaData, cfg: SeaConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.sea.algorithms import smoother

    return smoother.incremental(data, cfg, True, factors(data, cfg, ctx))  # (covariances every run: as gtsam's)


TABLE: dict[str, Estimator] = table(
    "sea",
    Estimator("geometric", geometric, (255, 170, 0), "algorithm 1: each step's angles through (3)-(5)",
              causal=True, covariances=False),
    Estimator("rls", rls, (60, 200, 90), "algorithm 2: diffuse RLS on AR models of the angles, l-step forecasts",
              causal=True, covariances=False),
    Estimator("window-rls", window_rls, (0, 210, 200), "algorithm 3: sliding-window diffuse RLS on the AR models",
              causal=True, covariances=False),
    Estimator("ekf", ekf, (230, 70, 70),
              "EKF on a constant-velocity target (the paper's reference [8])", causal=True, covariances=True),
    Estimator("gtsam", gtsam_batch, (190, 90, 240), "GTSAM LM smoother over the whole run (uses the future)",
              causal=False, covariances=True),
    Estimator("isam2", isam2, (255, 110, 200), "GTSAM iSAM2, the newest step at each step (causal)",
              causal=True, covariances=True),
)
