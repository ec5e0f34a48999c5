"""Configure -> simulate or load -> estimate (every estimator on the same pair) -> evaluate.

Each run draws its own scene (synthetic: a new terrain, texture and true attitude; ngi: the
same real pair) and its own navigation errors, seeded by ``(seed, run)``. Scored is the
orientation of image II (the one the paper corrects); errors are ``truth - estimate``. The
unrefined orientation from the navigation system is the estimator ``navigation``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from workbench import montecarlo
from workbench.errors import require
from workbench.estimation import metrics
from workbench.estimation.angles import wrap
from workbench.experiments.terrain import halftone, navigation, search
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.scene import Scene, synthetic_scene

SEARCH = "recurrent-search"
REFINED = "recurrent-search-refined"
ITERATED = "recurrent-search-iterated"


@dataclass
class Estimate:
    """Both exposures' orientation as an estimator gives it."""

    position: np.ndarray     # (2, 3)
    angles: np.ndarray       # (2, 3)
    seconds: float = 0.0
    extras: dict = field(default_factory=dict)


@dataclass
class RunResult:
    scene: Scene
    state: np.ndarray                     # the true error state
    measured: Estimate
    estimates: dict[str, Estimate]
    search: search.SearchResult | None
    ground_errors: dict[str, np.ndarray]  # per-pixel ground error maps of image II
    scene_mode: str = "common"            # the error mode (names the state's components)


def make_scene(cfg: TerrainConfig, rng: np.random.Generator) -> Scene:
    if cfg.scene == "ngi":
        from workbench.experiments.terrain import ngi

        return ngi.load(cfg)
    return synthetic_scene(cfg, rng)


def run_estimators(cfg: TerrainConfig, scene: Scene, meas: Estimate, rng: np.random.Generator,
                   search_progress: Callable[[int], None] | None = None, threads: int = 1
                   ) -> tuple[dict[str, Estimate], search.SearchResult | None]:
    """Every selected estimator on the same measured pair, each timed."""
    out: dict[str, Estimate] = {"navigation": meas}
    m = navigation.error_map(cfg.mode, scene.interval)
    result = None
    if SEARCH in cfg.estimators:
        t0 = time.perf_counter()
        problem = search.make_problem(cfg, scene.k, scene.dem, meas.position, meas.angles, scene.images,
                                      scene.interval)
        hyp = search.hypotheses(cfg, rng)
        result = search.run(problem, hyp, cfg.bank, cfg.chunk_mb, progress=search_progress, threads=threads)
        seconds = time.perf_counter() - t0
        t1 = time.perf_counter()
        state_it, cov_it, n_it = search.iterate(problem, result.centre, hyp.prior, result.refinement)
        seconds_it = seconds + time.perf_counter() - t1
        m2 = m[1, :3]  # image II's position errors from the state
        for name, state, cov, sec in ((SEARCH, result.centre, None, seconds),
                                      (REFINED, result.refinement, result.covariance[result.winner], seconds),
                                      (ITERATED, state_it, cov_it, seconds_it)):
            pos, ang = navigation.corrected(meas.position, meas.angles, m @ state)
            out[name] = Estimate(pos, ang, sec, {"state": state})
            if cov is not None:
                out[name].extras["position_cov"] = m2 @ cov @ m2.T
        out[ITERATED].extras["iterations"] = n_it
    if "gtsam-ba" in cfg.estimators:
        from workbench.experiments.terrain import ba

        t0 = time.perf_counter()
        est = ba.adjust(cfg, scene, meas.position, meas.angles)
        est.seconds = time.perf_counter() - t0
        out["gtsam-ba"] = est
    return out, result


def run_once(cfg: TerrainConfig, run: int, trace: bool = False,
             search_progress: Callable[[int], None] | None = None, threads: int = 1) -> RunResult:
    """One run; ``trace`` keeps full-resolution ground error maps (for the recording)."""
    rng = np.random.default_rng([cfg.seed, run])
    scene = make_scene(cfg, rng)
    state = navigation.draw_state(cfg, rng)
    pose_err = navigation.error_map(cfg.mode, scene.interval) @ state
    meas = Estimate(*navigation.measured(scene.position, scene.angles, pose_err))
    estimates, result = run_estimators(cfg, scene, meas, rng, search_progress, threads)
    step = 1 if trace else max(1, min(scene.k.width, scene.k.height) // 100)
    truth = (scene.position[1], scene.angles[1])
    ground = {name: halftone.ground_error(scene.dem, scene.k, truth, (e.position[1], e.angles[1]), step)
              for name, e in estimates.items()}
    return RunResult(scene, state, meas, estimates, result, ground, cfg.mode)


@dataclass
class RunSummary:
    """What a Monte Carlo worker sends back: small arrays only."""

    run: int
    position: dict[str, np.ndarray]   # (3,) truth - estimate, image II
    attitude: dict[str, np.ndarray]   # (3,) rad
    ground_rmse: dict[str, float]
    seconds: dict[str, float]
    nees: dict[str, float]            # image II's position NEES (3 dof) where the estimator has a covariance
    winner_in_true_cell: bool | None
    winner_in_true_position_cell: bool | None
    hypotheses: int
    nodes: int


def summarise(res: RunResult, run: int) -> RunSummary:
    sc = res.scene
    pos = {n: sc.position[1] - e.position[1] for n, e in res.estimates.items()}
    att = {n: wrap(sc.angles[1] - e.angles[1]) for n, e in res.estimates.items()}
    rm = {n: halftone.rmse(g) for n, g in res.ground_errors.items()}
    sec = {n: e.seconds for n, e in res.estimates.items()}
    nees = {}
    for n, e in res.estimates.items():
        cov = e.extras.get("position_cov")
        if cov is not None and np.all(np.isfinite(cov)) and np.linalg.det(cov) > 0:
            nees[n] = float(metrics.nees(pos[n], cov))
    hit = hit_linear = None
    if res.search is not None and res.search.kind == "grid":
        s = res.search
        spacing = np.ptp(s.centres, axis=0) / np.maximum(1, np.array([len(np.unique(c)) - 1 for c in s.centres.T]))
        searched = np.ptp(s.centres, axis=0) > 0
        inside = np.abs(s.centre - res.state) <= 0.5 * spacing + 1e-12
        hit = bool(np.all(inside[searched]))
        linear = np.array([n in navigation.LINEAR for n in navigation.STATE[res.scene_mode]]) & searched
        hit_linear = bool(np.all(inside[linear]))
    return RunSummary(run, pos, att, rm, sec, nees, hit, hit_linear,
                      0 if res.search is None else len(res.search.centres),
                      0 if res.search is None else res.search.nodes)


def _worker(args: tuple[TerrainConfig, int]) -> RunSummary:
    cfg, run = args
    return summarise(run_once(cfg, run), run)


def monte_carlo(cfg: TerrainConfig, first: RunResult | None = None, jobs: int | None = None,
                progress: Callable[[int], None] | None = None) -> list[RunSummary]:
    """Runs ``0 .. runs-1`` (run 0 may be given, already computed with its trace)."""
    return montecarlo.run_all(_worker, cfg, cfg.runs, summarise(first, 0) if first is not None else None,
                              jobs, progress)


def _paper_fractions(pos: np.ndarray, max_linear: float) -> dict[str, float]:
    """The paper's Fig. 3 quantities: mean and standard deviation of |dX|, |dY| and the radial
    error sqrt(dX^2 + dY^2) over runs, as fractions of the maximum linear error."""
    ax, ay = np.abs(pos[:, 0]) / max_linear, np.abs(pos[:, 1]) / max_linear
    ar = np.hypot(pos[:, 0], pos[:, 1]) / max_linear
    return {"mean_x": float(ax.mean()), "std_x": float(ax.std()), "mean_y": float(ay.mean()),
            "std_y": float(ay.std()), "mean_r": float(ar.mean()), "std_r": float(ar.std())}


def statistics(cfg: TerrainConfig, runs: list[RunSummary], label: str = "") -> dict:
    """The metrics JSON: per estimator, image II's mean position error (m, 3D norm), mean
    attitude error (rad, norm of the three angles), ground RMSE of the halftone model (m, RMS
    over runs), seconds; ``reduction`` is the mean position error over ``navigation``'s; the
    paper's normalised statistics in ``paper``."""
    require(len(runs) > 0, "no runs to summarise")
    out: dict = {"experiment": "terrain", "scene": cfg.scene, "mode": cfg.mode, "seed": cfg.seed,
                 "runs": len(runs), "label": label, "size": cfg.size, "distribution": cfg.distribution,
                 "max_linear": cfg.max_linear, "max_angular": cfg.max_angular, "config": cfg.to_json(),
                 "units": {"position_error": "m", "attitude_error": "rad", "ground_rmse": "m", "seconds": "s"},
                 "hypotheses": runs[0].hypotheses, "nodes": runs[0].nodes, "estimators": {}}
    hits = [r.winner_in_true_cell for r in runs if r.winner_in_true_cell is not None]
    out["winner_in_true_cell"] = float(np.mean(hits)) if hits else None
    hits = [r.winner_in_true_position_cell for r in runs if r.winner_in_true_position_cell is not None]
    out["winner_in_true_position_cell"] = float(np.mean(hits)) if hits else None
    nav_pos = np.mean([np.linalg.norm(r.position["navigation"]) for r in runs])
    nav_att = np.mean([np.linalg.norm(r.attitude["navigation"]) for r in runs])
    nav_ground = np.sqrt(np.mean([r.ground_rmse["navigation"] ** 2 for r in runs]))
    for name in runs[0].position:
        pos = np.stack([r.position[name] for r in runs])
        att = np.stack([r.attitude[name] for r in runs])
        pe = np.linalg.norm(pos, axis=1)
        ae = np.linalg.norm(att, axis=1)
        ground = np.sqrt(np.mean([r.ground_rmse[name] ** 2 for r in runs]))
        out["estimators"][name] = {
            "position_error": float(pe.mean()),
            "position_error_std": float(pe.std()),
            "attitude_error": float(ae.mean()),
            "ground_rmse": float(ground),
            "seconds": float(np.mean([r.seconds[name] for r in runs])),
            "reduction": float(pe.mean() / nav_pos) if nav_pos > 0 else None,
            "attitude_reduction": float(ae.mean() / nav_att) if nav_att > 0 else None,
            "ground_reduction": float(ground / nav_ground) if nav_ground > 0 else None,
            "rmse": {"x": float(np.sqrt(np.mean(pos[:, 0] ** 2))), "y": float(np.sqrt(np.mean(pos[:, 1] ** 2))),
                     "h": float(np.sqrt(np.mean(pos[:, 2] ** 2)))},
            "paper": _paper_fractions(pos, cfg.max_linear),
        }
        nees = [r.nees[name] for r in runs if name in r.nees]
        if nees:
            lo, hi = metrics.chi2_band(3, len(nees))
            out["estimators"][name]["anees"] = float(np.mean(nees))
            out["estimators"][name]["nees_band"] = [lo, hi]
    return out
