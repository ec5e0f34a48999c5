"""**Evaluate**: a run's errors and summary, and the statistics of Table 2 over runs.

Errors are ``truth - estimate`` per step; a run's summary keeps small arrays only (what a
Monte Carlo worker sends back); the statistics are time averages per run, then the mean and
spread over runs; the Monte Carlo curves are per-step RMS and ANEES over runs.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from workbench.estimation import metrics
from workbench.estimation.angles import to_arcmin, wrap
from workbench.experiments.sea import bounds as sea_bounds
from workbench.experiments.sea.config import ALL_SHIPS, SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.paper import TABLE2
from workbench.experiments.sea.run import RunResult, run_once
from workbench.experiments.sea.scenario import SeaData

QUANTITIES = ("x", "y", "alpha", "beta", "range")


def errors(data: SeaData, est: Estimate) -> np.ndarray:
    """Errors ``truth - estimate`` per step: x, y (m), alpha, beta (rad), range (m)."""
    return np.stack([
        data.target[:, 0] - est.position[:, 0],
        data.target[:, 1] - est.position[:, 1],
        wrap(data.alpha - est.alpha),
        data.beta - est.beta,
        data.range - est.range,
    ], axis=1)


@dataclass
class RunSummary:
    """What a Monte Carlo worker sends back: small arrays, no GTSAM objects."""

    run: int
    errors: dict[str, np.ndarray]
    nees: dict[str, np.ndarray]
    forecast_err: dict[str, np.ndarray]       # (T, 4) l-step errors x, y (m), alpha, beta (rad)
    forecast_unusable: dict[str, np.ndarray]  # (T,) an angle forecast with beta <= 0
    seconds: dict[str, float]
    seen: np.ndarray
    t: np.ndarray
    transient: dict[str, np.ndarray] = field(default_factory=dict)
    simulated: dict[str, np.ndarray] | None = None  # errors on simulated angles (``from_images``)
    image: dict | None = None                       # the image stage's errors and flags
    failed: dict[str, str] = field(default_factory=dict)  # estimators that failed: one line each
    delays: dict[str, float] = field(default_factory=dict)  # each estimator's delay (its bound)
    bounds: dict[float, dict[str, np.ndarray]] = field(default_factory=dict)  # delay -> quantity -> (T,)
    ship: int | None = None                         # ais: the ship's MMSI
    label: str = ""                                 # the dataset's label
    repairs: dict = field(default_factory=dict)     # what reading the real files repaired


def summarise(result: RunResult, cfg: SeaConfig, run: int) -> RunSummary:
    """The run's errors, NEES, forecast errors, impulse transient and image-stage figures."""
    data = result.data
    errs = {name: errors(data, e) for name, e in result.estimates.items()}
    nees, fc, unusable = {}, {}, {}
    truth = data.target
    for name, est in result.estimates.items():
        if est.state_cov is not None:
            e = truth - np.concatenate([est.position, est.velocity], axis=1)
            ok = np.all(np.isfinite(e), axis=1)
            n = np.full(data.steps, np.nan)
            n[ok] = metrics.nees(e[ok], est.state_cov[ok])
            nees[name] = n
        if est.forecast is not None:
            fc[name], unusable[name] = forecast_errors(data, est)
    transient = {}
    if cfg.scenario == "impulse" and not cfg.from_images:  # (it would render the run again)
        transient = impulse_transient(result, errs, cfg, run)
    image = None
    st = result.images
    if st is not None:
        image = {"errors": st.errors(data), "detected": st.detected, "visible": st.visible,
                 "horizon": st.true_horizon[:, 0] - st.horizon[:, 0],
                 "tilt": st.tilt - st.tilt_est, "roll": st.roll - st.roll_est,
                 "reasons": [r.split(":")[0] for r in st.reasons if r],
                 "seconds": (st.seconds_render, st.seconds_detect), "arcmin_per_px": st.camera.arcmin_per_pixel,
                 "size": (st.camera.width, st.camera.height), "pan": st.camera.pan}
    seen = result.scenario_seen if result.scenario_seen is not None else data.seen
    simulated = None
    if result.simulated is not None:
        sim_data, sim = result.simulated
        simulated = {name: errors(sim_data, e) for name, e in sim.items()}
    delays = {n: result.estimators[n].delay for n in result.estimates if n in result.estimators}
    crb = {}
    if st is None:  # angles from images have the image stage's noise, not the model's: no bound
        truth = sea_bounds.Truth(data.target, data.observer, data.seen, data.disturbed)
        model = sea_bounds.Model(data.dt, data.height, data.sigma_acc, data.sigma_alpha, data.sigma_beta,
                                 data.sigma_observer, cfg.prior_speed,
                                 float(np.deg2rad(cfg.impulse_sigma_deg)) if cfg.scenario == "impulse" else 0.0)
        b = sea_bounds.Bounds(model, [truth])
        crb = {d: {q: v[0] for q, v in b.variances(d).items()} for d in {0.0, float("inf"), *delays.values()}}
    return RunSummary(run, errs, nees, fc, unusable,
                      {n: e.seconds for n, e in result.estimates.items()}, seen, data.t,
                      transient, simulated, image, dict(result.failed), delays, crb, data.ship, data.label,
                      dict(data.repairs or {}))


def bound_variances(runs: list[RunSummary], delay: float) -> dict[str, np.ndarray] | None:
    """The runs' Cramér-Rao variance bounds for that delay, quantity -> ``(runs, T)`` (rad^2 for
    the angles), or None where there are none (angles from images)."""
    if not runs[0].bounds or delay not in runs[0].bounds:
        return None
    return {q: np.stack([r.bounds[delay][q] for r in runs]) for q in sea_bounds.QUANTITIES}


def bound_kind(delay: float) -> str:
    return "filtering" if delay == 0 else "smoothing" if np.isinf(delay) else f"fixed-lag {delay:g} s"


def forecast_errors(data: SeaData, est: Estimate) -> tuple[np.ndarray, np.ndarray]:
    """Errors of the forecasts made at each step for ``L`` steps ahead, and the unusable ones.

    ``(T, 4)``: x, y (m) of the forecast position, and, where the estimator forecasts the
    angles (algorithms 2-3), alpha and beta (rad); NaN where there is no forecast or the
    run ends first. Unusable ``(T,)``: an angle forecast whose elevation is at or above the
    horizon (``beta <= 0``), so (3)-(5) give it no position.
    """
    T, L = data.steps, est.forecast.shape[1]
    err = np.full((T, 4), np.nan)
    unusable = np.zeros(T, bool)
    err[: T - L, :2] = data.target[L:, :2] - est.forecast[: T - L, L - 1]
    if est.forecast_angles is not None:
        ahead = est.forecast_angles[: T - L, L - 1]
        err[: T - L, 2] = wrap(data.alpha[L:] - ahead[:, 0])
        err[: T - L, 3] = data.beta[L:] - ahead[:, 1]
        with np.errstate(invalid="ignore"):
            unusable[: T - L] = np.isfinite(ahead[:, 0]) & (ahead[:, 1] <= 0)
    return err, unusable


TRANSIENT_SKIP = ("isam2",)
"""Estimators left out of the impulse transient (it reruns each one on the undisturbed data)."""


def impulse_transient(result: RunResult, errs: dict[str, np.ndarray], cfg: SeaConfig, run: int
                      ) -> dict[str, np.ndarray]:
    """Azimuth error caused by the impulse alone: the run minus the same run without it.

    ``simulate`` draws the impulse after every other noise, so the ``paper`` scenario with
    the same seed and run is the identical run, undisturbed; the difference of the two
    errors is the transient, free of the ordinary noise.
    """
    clean = run_once(replace(cfg, scenario="paper"),
                     run, [e for n, e in result.estimators.items() if n not in TRANSIENT_SKIP and n in errs])
    return {n: errs[n][:, 2] - errors(clean.data, e)[:, 2] for n, e in clean.estimates.items()}


def curves(runs: list[RunSummary]) -> dict[str, dict[str, np.ndarray]]:
    """Per estimator, per step over runs: ``position_rmse`` (m, where some run has an
    estimate) and, for those with a state covariance, ``nees`` (the mean over runs)."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for name in runs[0].errors:
        E = np.stack([r.errors[name][:, :2] for r in runs])
        entry = {}
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # steps no run has (a bad frame in each)
            if np.isfinite(E).any():
                entry["position_rmse"] = np.sqrt(np.nanmean(np.sum(E**2, axis=2), axis=0))
            if name in runs[0].nees:
                entry["nees"] = np.nanmean(np.stack([r.nees[name] for r in runs]), axis=0)
        out[name] = entry
    return out


def statistics(cfg: SeaConfig, runs: list[RunSummary], label: str = "") -> dict:
    """Table 2's statistics per estimator (mean and spread over runs) as the metrics JSON."""
    names = list(runs[0].errors)
    T = len(runs[0].t)
    result: dict = {"experiment": "sea", "scenario": cfg.scenario, "seed": cfg.seed,
                    "runs": len(runs), "steps": T, "label": label, "config": cfg.to_json(),
                    "units": {"x": "m", "y": "m", "range": "m", "alpha": "arcmin",
                              "beta": "arcmin", "seconds": "s", "recovery": "s",
                              "forecast": "m (position), arcmin (alpha, beta)"},
                    "paper_table2": TABLE2, "estimators": {}}
    scale = np.array([1.0, 1.0, to_arcmin(1.0), to_arcmin(1.0), 1.0])
    for name in names:
        raw = np.stack([r.errors[name] for r in runs])
        E = raw * scale  # (runs, T, 5)
        b = metrics.bias(E, axis=1)
        rm = metrics.rmse(E, axis=1)
        mx = metrics.max_abs(E, axis=1)
        entry: dict = {
            "rmse": _named(rm.mean(axis=0)), "rmse_std": _named(rm.std(axis=0)),
            "bias": _named(b.mean(axis=0)), "bias_std": _named(b.std(axis=0)),
            "max": _named(mx.mean(axis=0)),
            "position_rmse": float(np.sqrt(np.nanmean(E[..., 0] ** 2 + E[..., 1] ** 2))),
            "coverage": float(np.mean(np.isfinite(E[..., 0]))),
            "seconds": float(np.mean([r.seconds[name] for r in runs])),
        }
        delay = runs[0].delays.get(name, 0.0)
        V = bound_variances(runs, delay)
        if V is not None:
            entry["bound"], entry["efficiency"], entry["efficiency_se"] = sea_bounds.summary(
                V, raw, {"alpha": to_arcmin(1.0), "beta": to_arcmin(1.0)})
            entry["bound_kind"] = bound_kind(delay)
        if name in runs[0].transient:
            D = np.stack([r.transient[name] for r in runs]) * scale[2]
            entry["recovery"] = _recovery(cfg, runs[0].t, D, cfg.sigma_alpha_arcmin)
        lost = ~runs[0].seen  # the same steps in every run: the scenario's loss window
        if lost.any() and np.isfinite(E[:, lost, 0]).any():
            entry["rmse_during_loss"] = _named(metrics.rmse(E[:, lost].reshape(-1, 5), axis=0))
        if name in runs[0].nees:
            N = np.stack([r.nees[name] for r in runs])
            per_step = np.nanmean(N, axis=0)
            lo, hi = metrics.chi2_band(4, len(runs))
            entry["anees"] = float(np.nanmean(per_step))
            entry["anees_band"] = [lo, hi]
            entry["nees_inside_band"] = float(np.nanmean((per_step >= lo) & (per_step <= hi)))
        if name in runs[0].forecast_err:
            F = np.stack([r.forecast_err[name] for r in runs])
            U = np.stack([r.forecast_unusable[name] for r in runs])
            entry["forecast"] = _forecast_stats(cfg, F, U)
            entry["forecast_rmse"] = {**entry["forecast"]["position"]["rmse"], "steps": cfg.horizon}
        result["estimators"][name] = entry
    if runs[0].image is not None:
        result["images"] = image_statistics(runs)
    if runs[0].repairs:
        result["data_repairs"] = dict(runs[0].repairs)
    if cfg.scenario == "ais" and cfg.mmsi == ALL_SHIPS:
        result.update(ship_statistics(cfg, runs))
    if runs[0].simulated is not None:
        sim = [replace(r, errors=r.simulated, nees={}, forecast_err={}, forecast_unusable={}, transient={},
                       simulated=None, image=None, failed={}, bounds={}) for r in runs]
        result["simulated"] = {"note": "the same runs' estimators on the simulated angles",
                               "estimators": statistics(cfg, sim, label)["estimators"]}
    return result


SHIP_FIGURES = (("position_rmse", None), ("rmse", "x"), ("rmse", "y"), ("rmse", "alpha"), ("rmse", "beta"))
"""The per-ship figures summarised over ships: position RMSE and the RMSE of x, y (m), alpha, beta (arcmin)."""


def ship_statistics(cfg: SeaConfig, runs: list[RunSummary]) -> dict:
    """``--mmsi all``: each ship's statistics over its own runs (as ``--mmsi <ship>`` gives them),
    the median and the worst ship per estimator and figure, and the ships left out with the reason.

    Returns ``ships`` (MMSI -> label, runs, per estimator position_rmse and Table 2's rmse and
    bias), ``over_ships`` (estimator -> figure -> median, worst, worst_mmsi, mean), ``ships_skipped``
    (MMSI -> reason) and a ``label``.
    """
    from workbench.experiments.sea.readers import ais

    groups: dict[int, list[RunSummary]] = {}
    for r in runs:
        groups.setdefault(int(r.ship), []).append(r)
    ships = {}
    for mmsi, rs in groups.items():
        st = statistics(replace(cfg, mmsi=mmsi), rs, rs[0].label)
        ships[str(mmsi)] = {"label": rs[0].label, "runs": len(rs), "estimators": {
            name: {"position_rmse": e["position_rmse"], "rmse": e["rmse"], "bias": e["bias"]}
            for name, e in st["estimators"].items()}}
    over: dict = {}
    for name in runs[0].errors:
        over[name] = {}
        for key, q in SHIP_FIGURES:
            values = np.array([s["estimators"][name][key] if q is None else s["estimators"][name][key][q]
                               for s in ships.values()])
            worst = int(np.nanargmax(values)) if np.isfinite(values).any() else 0
            over[name][key if q is None else f"rmse_{q}"] = {
                "median": float(np.nanmedian(values)), "worst": float(values[worst]),
                "worst_mmsi": int(list(ships)[worst]), "mean": float(np.nanmean(values))}
    _, skipped = ais.ship_set(cfg.data, cfg.duration, cfg.ais_max_gap)
    return {"ships": ships, "over_ships": over, "ships_skipped": {str(m): why for m, why in skipped.items()},
            "label": f"every usable ship: {len(ships)} run, {len(skipped)} skipped"}


def image_statistics(runs: list[RunSummary]) -> dict:
    """The image stage over runs: angle and pixel errors (truth minus measurement) where detected,
    per-run bias and RMSE averaged over runs (with their spread); the detection rate over the
    frames where the object was drawn inside the frame."""
    E = np.stack([r.image["errors"] for r in runs])              # (runs, T, 4)
    E = E * np.array([to_arcmin(1.0), to_arcmin(1.0), 1.0, 1.0])
    with np.errstate(invalid="ignore"):
        b = np.nanmean(E, axis=1)
        rm = np.sqrt(np.nanmean(E**2, axis=1))
    det = np.stack([r.image["detected"] for r in runs])
    vis = np.stack([r.image["visible"] for r in runs])
    hz = np.stack([r.image["horizon"] for r in runs])
    tilt = to_arcmin(np.stack([r.image["tilt"] for r in runs]))
    roll = to_arcmin(np.stack([r.image["roll"] for r in runs]))
    reasons: dict[str, int] = {}
    for r in runs:
        for why in r.image["reasons"]:
            reasons[why] = reasons.get(why, 0) + 1
    render = np.sum([r.image["seconds"][0] for r in runs])
    detect = np.sum([r.image["seconds"][1] for r in runs])
    frames = det.size
    pair = ("alpha", "beta")

    def named(v, keys):
        return {k: float(x) for k, x in zip(keys, v, strict=True)}

    return {
        "size": list(runs[0].image["size"]), "arcmin_per_px": runs[0].image["arcmin_per_px"],
        "pan_deg": float(np.rad2deg(runs[0].image["pan"])),
        "errors": "truth minus measurement, where detected",
        "rmse": named(rm.mean(axis=0)[:2], pair), "rmse_std": named(rm.std(axis=0)[:2], pair),
        "bias": named(b.mean(axis=0)[:2], pair), "bias_std": named(b.std(axis=0)[:2], pair),
        "rmse_px": named(rm.mean(axis=0)[2:], ("u", "v")), "bias_px": named(b.mean(axis=0)[2:], ("u", "v")),
        "detection_rate": float((det & vis).sum() / max(vis.sum(), 1)),
        "false_detections": int((det & ~vis).sum()), "frames": int(frames), "visible_frames": int(vis.sum()),
        "no_detection": reasons,
        "horizon": {"rmse_px": _rms(hz[np.isfinite(hz)]), "bias_px": _stat(np.mean, hz[np.isfinite(hz)]),
                    "tilt_rmse_arcmin": _rms(tilt[np.isfinite(tilt)]),
                    "roll_rmse_arcmin": _rms(roll[np.isfinite(roll)])},
        "seconds_per_frame": {"render": float(render / frames), "detect": float(detect / frames)},
        "frames_per_second": {"detect": float(frames / max(detect, 1e-9)),
                              "render_and_detect": float(frames / max(render + detect, 1e-9))},
    }


def _forecast_stats(cfg: SeaConfig, F: np.ndarray, unusable: np.ndarray) -> dict:
    """The l-step forecast errors ``F (runs, T, 4)`` pooled over runs and steps.

    The AR forecasts (algorithms 2-3) are of the angles; their positions come through
    (3)-(5), where a forecast elevation near zero gives a range of kilometres and one at or
    above the horizon none at all. A few such forecasts (from the first, barely determined
    fits) rule any RMSE, so the figures that describe the forecasts are the median and the
    90th percentile of the absolute errors (positions: the distance), with the count of
    unusable forecasts; the RMSEs are kept for completeness (``null`` if they overflow).
    """
    pos = np.all(np.isfinite(F[..., :2]), axis=-1)
    ang = np.all(np.isfinite(F[..., 2:]), axis=-1)
    made = pos | ang
    dist = np.hypot(F[..., 0], F[..., 1])[pos]
    out: dict = {
        "steps": cfg.horizon, "seconds_ahead": cfg.horizon * cfg.dt,
        "count": int(made.sum()), "unusable": int(unusable.sum()),
        "unusable_fraction": float(unusable.sum() / max(made.sum(), 1)),
        "position": {"median": _stat(np.median, dist), "p90": _stat(np.percentile, dist, 90),
                     "rmse": {"x": _rms(F[..., 0][pos]), "y": _rms(F[..., 1][pos])}},
    }
    if ang.any():
        for q, i in (("alpha", 2), ("beta", 3)):
            e = np.abs(to_arcmin(F[..., i][ang]))
            out[q] = {"median_abs": _stat(np.median, e), "p90_abs": _stat(np.percentile, e, 90),
                      "rmse": _rms(e)}
    return out


def _stat(fn: Callable, x: np.ndarray, *args) -> float | None:
    return float(fn(x, *args)) if x.size else None


def _rms(x: np.ndarray) -> float | None:
    with np.errstate(over="ignore"):
        v = float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")
    return v if np.isfinite(v) else None


def _named(v: np.ndarray) -> dict[str, float]:
    return {q: float(x) for q, x in zip(QUANTITIES, v, strict=True)}


def _recovery(cfg: SeaConfig, t: np.ndarray, transient: np.ndarray, level: float) -> dict:
    """How long after the impulse the azimuth transient stays above the camera's noise.

    ``transient`` (runs, T) is the impulse's own effect on the azimuth error (arcmin);
    recovery is the last time its RMS over runs exceeds ``level`` (sigma_alpha), minus the
    impulse's end; ``settled`` is False if it still exceeds it at the end of the run.
    """
    rms = np.sqrt(np.nanmean(transient**2, axis=0))
    over = np.flatnonzero((t >= cfg.impulse_start) & (rms > level))
    last = t[over[-1]] if over.size else cfg.impulse_end
    return {"seconds": float(max(0.0, last - cfg.impulse_end)), "level_arcmin": level,
            "settled": not bool(over.size and over[-1] == len(t) - 1),
            "peak_arcmin": float(np.nanmax(rms))}


RUN_METRICS = {"position_rmse": "m", "rmse_x": "m", "rmse_y": "m", "rmse_alpha": "arcmin", "rmse_beta": "arcmin",
               "bias_x": "m", "bias_y": "m", "anees": "4 states", "coverage": "fraction", "seconds": "s",
               "position_bound": "m", "position_efficiency": "RMSE / bound"}
"""The per-run figures of a sweep's tidy table, and their units."""


def run_metrics(summary: RunSummary, cfg: SeaConfig) -> dict[str, dict[str, float]]:
    """One run's figures per estimator (a sweep's rows): RMSEs and biases over the run's steps
    (so their mean over runs is Table 2's), the position RMSE, the time-averaged NEES, the
    share of steps with an estimate, the seconds; the position's Cramér-Rao bound from this run
    alone and the efficiency against it."""
    out = {}
    for name, E in summary.errors.items():
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            rm = metrics.rmse(E, axis=0)
            b = metrics.bias(E, axis=0)
            entry = {"position_rmse": float(np.sqrt(np.nanmean(E[:, 0] ** 2 + E[:, 1] ** 2))),
                     "rmse_x": float(rm[0]), "rmse_y": float(rm[1]), "rmse_alpha": float(to_arcmin(rm[2])),
                     "rmse_beta": float(to_arcmin(rm[3])), "bias_x": float(b[0]), "bias_y": float(b[1]),
                     "coverage": float(np.mean(np.isfinite(E[:, 0]))), "seconds": float(summary.seconds[name])}
            if name in summary.nees:
                entry["anees"] = float(np.nanmean(summary.nees[name]))
            V = bound_variances([summary], summary.delays.get(name, 0.0))
            if V is not None:
                bound, eff, _ = sea_bounds.summary(V, E[None], {})
                entry["position_bound"], entry["position_efficiency"] = bound["position"], eff["position"]
        out[name] = entry
    return out
