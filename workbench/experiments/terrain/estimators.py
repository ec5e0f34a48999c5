"""The terrain experiment's estimator table: name -> how to run it, colour, what it is.

Each runner is ``(data, cfg, ctx) -> Estimate`` and imports its module when first run. The
three recurrent-search estimates share one search of the hypotheses (:func:`search`). There is
one epoch (the pair), so every estimator here is trivially causal.

Covariances (:mod:`.posterior`): the refinement's and the iterated filter's are their mean
squared error under the search's posterior (the navigation system's prior, the likelihood
tempered by the nodes' measured variance inflation), which does not assume the winning cell is
the true one; ``recurrent-search-posterior`` is that posterior's mode. The winning cell's
centre keeps its position (the paper's estimate) and takes its attitude from the posterior:
the cells do not resolve the angles (:attr:`search.SearchResult.centre`).
"""

from __future__ import annotations

from workbench.core.estimator import Estimator, RunContext, table
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.estimate import Estimate

SEARCH = "recurrent-search"
REFINED = "recurrent-search-refined"
ITERATED = "recurrent-search-iterated"
POSTERIOR = "recurrent-search-posterior"


def navigation(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    """The navigation system's orientation itself: the reference every reduction is against."""
    m = data.measured
    return Estimate(m.position.copy(), m.angles.copy())


def search(data, cfg: TerrainConfig, ctx: RunContext):
    """The recurrent search over the hypotheses, once a run: ``(problem, hypotheses, result)``."""
    from workbench.experiments.terrain.algorithms import search as rs

    def make():
        sc, meas = data.scene, data.measured
        problem = rs.make_problem(cfg, sc.k, sc.dem, meas.position, meas.angles, sc.images, sc.interval)
        hyp = rs.hypotheses(cfg, data.hypothesis_rng())
        return problem, hyp, rs.run(problem, hyp, cfg.bank, cfg.chunk_mb, threads=ctx.threads)

    return ctx.shared("search", make)


def in_cell(data, cfg: TerrainConfig, ctx: RunContext):
    """The winning filter iterated inside its cell (:func:`search.iterate`, the cell's prior), once
    a run: ``(state, covariance, iterations)``."""
    from workbench.experiments.terrain.algorithms import search as rs

    problem, hyp, result = search(data, cfg, ctx)  # each user is charged the search's time too

    def make():
        return rs.iterate(problem, result.centre, hyp.prior, result.refinement)

    return ctx.shared("iterated", make)


def posterior(data, cfg: TerrainConfig, ctx: RunContext):
    """The search's tempered posterior under the navigation prior, from the filter iterated in
    its cell (:func:`.posterior.posterior`), once a run."""
    from workbench.experiments.terrain import navigation as nav
    from workbench.experiments.terrain.algorithms import posterior as post

    problem, _, _ = search(data, cfg, ctx)
    start = in_cell(data, cfg, ctx)[0]

    def make():
        return post.posterior(problem, nav.prior_covariance(cfg), start)

    return ctx.shared("posterior", make)


def _corrected(data, state, cov=None, **extras) -> Estimate:
    from workbench.experiments.terrain import navigation as nav

    m = nav.error_map(data.mode, data.scene.interval)
    pos, ang = nav.corrected(data.measured.position, data.measured.angles, m @ state)
    m2 = m[1]  # image II's pose errors (position, angles) from the state
    pose_cov = None if cov is None else m2 @ cov @ m2.T
    return Estimate(pos, ang, extras={"state": state, **extras},
                    position_cov=None if pose_cov is None else pose_cov[:3, :3], pose_cov=pose_cov)


def centre(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    """The winning cell's centre for the position and velocity errors (the paper's estimate),
    the posterior's for the angles, which the cells do not resolve."""
    from workbench.experiments.terrain import navigation as nav

    _, _, result = search(data, cfg, ctx)
    state = result.centre.copy()
    angular = [i for i, n in enumerate(nav.STATE[data.mode]) if n in nav.ANGULAR]
    state[angular] = posterior(data, cfg, ctx).state[angular]
    return _corrected(data, state, cell_attitude=result.centre[angular])


def refined(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    """The winning filter's state; its covariance the mean squared error under the posterior
    (the filter's own ``Gamma_N`` is kept as the extra ``cell_covariance``)."""
    _, _, result = search(data, cfg, ctx)
    state = result.refinement
    return _corrected(data, state, posterior(data, cfg, ctx).mse(state),
                      cell_covariance=result.covariance[result.winner])


def iterated(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    """The winning filter iterated in its cell; covariance as :func:`refined`'s."""
    state, cov, n = in_cell(data, cfg, ctx)
    return _corrected(data, state, posterior(data, cfg, ctx).mse(state), iterations=n, cell_covariance=cov)


def tempered(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    """The posterior's mode and covariance (:mod:`.posterior`)."""
    p = posterior(data, cfg, ctx)
    return _corrected(data, p.state, p.covariance, iterations=p.iterations, kappa=p.kappa,
                      effective_nodes=p.effective_nodes, bandwidth=p.bandwidth, correlation=p.correlation)


def bundle_adjustment(data, cfg: TerrainConfig, ctx: RunContext) -> Estimate:
    from workbench.experiments.terrain.algorithms import ba

    return ba.adjust(cfg, data.scene, data.measured.position, data.measured.angles)


TABLE: dict[str, Estimator] = table(
    "terrain",
    Estimator("navigation", navigation, (235, 70, 70), "the navigation system's orientation, unrefined",
              causal=True, covariances=False),
    Estimator(SEARCH, centre, (255, 165, 0), "recurrent search (2)-(4): the winning hypothesis cell's centre "
              "(its angles: the posterior's)", causal=True, covariances=False),
    Estimator(REFINED, refined, (60, 215, 90), "the winning Kalman filter's state (the paper's refinement)",
              causal=True, covariances=True),
    Estimator(ITERATED, iterated, (40, 200, 230), "that filter re-linearised at its own estimate until it settles",
              causal=True, covariances=True),
    Estimator(POSTERIOR, tempered, (255, 105, 180), "the navigation prior instead of the cell's, the likelihood "
              "tempered by the nodes' measured correlation: damped Gauss-Newton from the iterated filter",
              causal=True, covariances=True),
    Estimator("gtsam-ba", bundle_adjustment, (190, 90, 240),
              "GTSAM bundle adjustment: SIFT tie points, navigation priors, DEM height factors, LM",
              causal=True, covariances=True),
)
