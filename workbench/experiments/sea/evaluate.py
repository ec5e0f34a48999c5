"""**Evaluate**: a run's errors and summary beside its metrics (:mod:`.metrics`, which give
Table 2's statistics), and what the metrics JSON holds beyond them: the impulse's transient, the
track loss, the forecasts, the image stage, every ship of ``--mmsi all``.

Errors are ``truth - estimate`` per step; a run's summary keeps small arrays only (what a
Monte Carlo worker sends back).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from workbench.core.experiment import RunSummary as Summary
from workbench.estimation import metrics
from workbench.estimation.angles import to_arcmin, wrap
from workbench.experiments.sea import bounds as sea_bounds
from workbench.experiments.sea.config import ALL_SHIPS, SeaConfig
from workbench.experiments.sea.estimate import Estimate
from workbench.experiments.sea.metrics import QUANTITIES, RENAMED, bounds, errors
from workbench.experiments.sea.paper import TABLE2
from workbench.experiments.sea.run import RunResult
from workbench.experiments.sea.scenario import SeaData
from workbench.metrics import base as metric
from workbench.metrics import statistics as figures
from workbench.metrics import truthfree


@dataclass
class RunSummary(Summary):
    """What a Monte Carlo worker sends back beside the metrics: small arrays, no GTSAM objects."""

    errors: dict[str, np.ndarray]
    forecast_err: dict[str, np.ndarray]       # (T, 4) l-step errors x, y (m), alpha, beta (rad)
    forecast_unusable: dict[str, np.ndarray]  # (T,) an angle forecast with beta <= 0
    seen: np.ndarray
    t: np.ndarray
    transient: dict[str, np.ndarray] = field(default_factory=dict)
    simulated: dict[str, dict[str, metric.Values]] | None = None  # the metrics on simulated angles (``from_images``)
    image: dict | None = None                       # the image stage's errors and flags
    delays: dict[str, float] = field(default_factory=dict)  # each estimator's delay (its bound)
    bounds: dict[float, dict[str, np.ndarray]] = field(default_factory=dict)  # delay -> quantity -> (T,)
    ship: int | None = None                         # ais: the ship's MMSI
    label: str = ""                                 # the dataset's label
    repairs: dict = field(default_factory=dict)     # what reading the real files repaired
    reference: str | None = None                    # no truth: ``errors`` are departures from this smoother


def summarise(result: RunResult, cfg: SeaConfig, run: int) -> RunSummary:
    """The run's errors, forecast errors, impulse transient, image-stage figures and bounds."""
    data = result.data
    errs = {name: errors(data, e) for name, e in result.estimates.items()}
    reference = None
    if not np.isfinite(data.target).any():  # a log without truth: the run 0 plots show each estimate's
        reference = truthfree.smoother(result.estimators, result.estimates)  # departure from the smoother
        if reference is not None:
            ref = result.estimates[reference]
            errs = {name: departures(ref, e) for name, e in result.estimates.items()}
    fc, unusable = {}, {}
    for name, est in result.estimates.items():
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
    if result.simulated is not None:  # the same metrics on the simulated angles (their own dataset)
        sim_data, sim = result.simulated
        ctx = metric.MetricContext(cfg, run, estimates=sim, estimators=result.estimators)
        simulated = metric.evaluate(result.metrics, sim_data, sim, ctx)[0]
    delays = {n: result.estimators[n].delay for n in result.estimates if n in result.estimators}
    b = result.shared("bounds", lambda: bounds(data, cfg))
    crb = {} if b is None else {d: {q: v[0] for q, v in b.variances(d).items()}
                                for d in {0.0, float("inf"), *delays.values()}}
    return RunSummary(run, errs, fc, unusable, seen, data.t, transient, simulated, image, delays, crb, data.ship,
                      data.label, dict(data.repairs or {}), reference, failed=dict(result.failed))


def departures(reference: Estimate, est: Estimate) -> np.ndarray:
    """``reference - estimate`` per step, as :func:`.metrics.errors` gives errors: x, y (m),
    alpha, beta (rad, alpha wrapped), range (m)."""
    return np.stack([reference.position[:, 0] - est.position[:, 0], reference.position[:, 1] - est.position[:, 1],
                     wrap(reference.alpha - est.alpha), reference.beta - est.beta, reference.range - est.range],
                    axis=1)


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
    rerun = [e for n, e in result.estimators.items() if n not in TRANSIENT_SKIP and n in errs]
    clean = result.experiment.run_once(replace(cfg, scenario="paper"), run, rerun)
    return {n: errs[n][:, 2] - errors(clean.data, e)[:, 2] for n, e in clean.estimates.items()}


def statistics(exp: Any, cfg: SeaConfig, runs: list[RunSummary], stats: dict) -> None:
    """What the metrics JSON holds beyond the metrics (Table 2's figures are metrics): the steps,
    the units, the paper's Table 2, and per estimator the bound it is held to, the impulse's
    transient, the errors during a track loss and the forecasts; the image stage, what reading
    real files repaired, every ship of ``--mmsi all``, the same runs on the simulated angles."""
    stats.update({"steps": len(runs[0].t), "paper_table2": TABLE2,
                  "units": {"x": "m", "y": "m", "range": "m", "alpha": "arcmin", "beta": "arcmin", "seconds": "s",
                            "recovery": "s", "forecast": "m (position), arcmin (alpha, beta)"}})
    scale = np.array([1.0, 1.0, to_arcmin(1.0), to_arcmin(1.0), 1.0])
    for name in runs[0].errors:
        entry = stats["estimators"].setdefault(name, {})
        delay = runs[0].delays.get(name, 0.0)
        if bound_variances(runs, delay) is not None:
            entry["bound_kind"] = bound_kind(delay)
        if name in runs[0].transient:
            D = np.stack([r.transient[name] for r in runs]) * scale[2]
            entry["recovery"] = _recovery(cfg, runs[0].t, D, cfg.sigma_alpha_arcmin)
        E = np.stack([r.errors[name] for r in runs]) * scale  # (runs, T, 5)
        lost = ~runs[0].seen  # the same steps in every run: the scenario's loss window
        if lost.any() and runs[0].reference is None and np.isfinite(E[:, lost, 0]).any():
            entry["rmse_during_loss"] = _named(metrics.rmse(E[:, lost].reshape(-1, 5), axis=0))
        if name in runs[0].forecast_err:
            F = np.stack([r.forecast_err[name] for r in runs])
            U = np.stack([r.forecast_unusable[name] for r in runs])
            entry["forecast"] = _forecast_stats(cfg, F, U)
            entry["forecast_rmse"] = {**entry["forecast"]["position"]["rmse"], "steps": cfg.horizon}
    if runs[0].image is not None:
        stats["images"] = image_statistics(runs)
    if runs[0].repairs:
        stats["data_repairs"] = dict(runs[0].repairs)
    if cfg.scenario == "ais" and cfg.mmsi == ALL_SHIPS:
        stats.update(ship_statistics(cfg, exp.metrics(cfg), runs))
    if runs[0].simulated is not None:
        found = figures.statistics(exp.metrics(cfg), [r.simulated for r in runs])
        stats["simulated"] = figures.add_renamed({"note": "the same runs' estimators on the simulated angles",
                                                  "estimators": found}, RENAMED)


SHIP_FIGURES = ("position_rmse", "rmse_x", "rmse_y", "rmse_alpha", "rmse_beta")
"""The per-ship figures summarised over ships: position RMSE and the RMSE of x, y (m), alpha, beta (arcmin)."""


def ship_statistics(cfg: SeaConfig, metrics: list[metric.Metric], runs: list[RunSummary]) -> dict:
    """``--mmsi all``: each ship's figures over its own runs (as ``--mmsi <ship>`` gives them),
    the median and the worst ship per estimator and figure, and the ships left out with the reason.

    Returns ``ships`` (MMSI -> label, runs, per estimator position_rmse and Table 2's rmse and
    bias), ``over_ships`` (estimator -> figure -> median, worst, worst_mmsi, mean), ``ships_skipped``
    (MMSI -> reason) and a ``label``.
    """
    from workbench.experiments.sea.readers import ais

    groups: dict[int, list[RunSummary]] = {}
    for r in runs:
        groups.setdefault(int(r.ship), []).append(r)
    keep = ("position_rmse", *(f"{g}_{q}" for g in ("rmse", "bias") for q in QUANTITIES))
    ships = {}
    for mmsi, rs in groups.items():
        found = figures.statistics(metrics, [r.metrics for r in rs])
        entries = {name: {k: e[k] for k in keep if k in e} for name, e in found.items()}
        renamed = {old: new for old, new in RENAMED.items() if old.split(".")[0] in ("rmse", "bias")}
        ships[str(mmsi)] = {"label": rs[0].label, "runs": len(rs),
                            "estimators": figures.add_renamed({"estimators": entries}, renamed)["estimators"]}
    over: dict = {}
    for name in runs[0].errors:
        over[name] = {}
        for key in SHIP_FIGURES:
            values = np.array([np.nan if s["estimators"][name].get(key) is None else s["estimators"][name][key]
                               for s in ships.values()], float)
            worst = int(np.nanargmax(values)) if np.isfinite(values).any() else 0
            over[name][key] = {"median": float(np.nanmedian(values)), "worst": float(values[worst]),
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
