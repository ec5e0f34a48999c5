"""The terrain experiment's estimator table: name -> how to run it, colour, what it is.

Each runner is ``(data, cfg, ctx) -> Estimate`` and imports its module when first run. The
three recurrent-search estimates share one search of the hypotheses (:func:`search`). There is
one epoch (the pair), so every estimator here is trivially causal.
"""

from __future__ import annotations

from workbench.experiments.contract import Estimator, RunContext, table
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.estimate import Estimate

SEARCH = "recurrent-search"
REFINED = "recurrent-search-refined"
ITERATED = "recurrent-search-iterated"


def navigation(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    """The navigation system's orientation itself: the reference every reduction is against."""
    m = data.measured
    return Estimate(m.position.copy(), m.angles.copy())


def search(data, cfg: TerrainConfig, ctx: RunContext):
    """The recurrent search over the hypotheses, once a run: ``(problem, hypotheses, result)``."""
    from workbench.experiments.terrain import search as rs

    def make():
        sc, meas = data.scene, data.measured
        problem = rs.make_problem(cfg, sc.k, sc.dem, meas.position, meas.angles, sc.images, sc.interval)
        hyp = rs.hypotheses(cfg, data.hypothesis_rng())
        return problem, hyp, rs.run(problem, hyp, cfg.bank, cfg.chunk_mb, threads=ctx.threads)

    return ctx.shared("search", make)


def _corrected(data, state, cov=None, **extras) -> Estimate:
    from workbench.experiments.terrain import navigation as nav

    m = nav.error_map(data.mode, data.scene.interval)
    pos, ang = nav.corrected(data.measured.position, data.measured.angles, m @ state)
    m2 = m[1]  # image II's pose errors (position, angles) from the state
    pose_cov = None if cov is None else m2 @ cov @ m2.T
    return Estimate(pos, ang, extras={"state": state, **extras},
                    position_cov=None if pose_cov is None else pose_cov[:3, :3], pose_cov=pose_cov)


def centre(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    _, _, result = search(data, cfg, ctx)
    return _corrected(data, result.centre)


def refined(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    _, _, result = search(data, cfg, ctx)
    return _corrected(data, result.refinement, result.covariance[result.winner])


def iterated(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.terrain import search as rs

    problem, hyp, result = search(data, cfg, ctx)
    state, cov, n = rs.iterate(problem, result.centre, hyp.prior, result.refinement)
    return _corrected(data, state, cov, iterations=n)


def bundle_adjustment(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.terrain import ba

    return ba.adjust(cfg, data.scene, data.measured.position, data.measured.angles)


TABLE: dict[str, Estimator] = table(
    "terrain",
    Estimator("navigation", navigation, (235, 70, 70), "the navigation system's orientation, unrefined",
              causal=True, covariances=False),
    Estimator(SEARCH, centre, (255, 165, 0), "recurrent search (2)-(4): the winning hypothesis cell's centre",
              causal=True, covariances=False),
    Estimator(REFINED, refined, (60, 215, 90), "the winning Kalman filter's state (the paper's refinement)",
              causal=True, covariances=True),
    Estimator(ITERATED, iterated, (40, 200, 230), "that filter re-linearised at its own estimate until it settles",
              causal=True, covariances=True),
    Estimator("gtsam-ba", bundle_adjustment, (190, 90, 240),
              "GTSAM bundle adjustment: SIFT tie points, navigation priors, DEM height factors, LM",
              causal=True, covariances=True),
)
