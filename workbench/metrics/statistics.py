"""A metric's figures (:mod:`.metric`), the same for every experiment: a run's figure (the
reduction of its counted samples: a sweep's row), the figures over runs as the metrics JSON's
keys, the curves over runs the recording draws, and the keys a release renamed.

Keys of the metrics JSON per estimator and metric ``m``: ``m`` (the figure over runs),
``m_std`` (the spread of the runs' figures, ``across="mean"``), ``m_band`` (the 95 % chi-square
band of the figure, where it has a dimension), ``m_inside_band`` (the share of scored steps where
the mean over runs is inside that band), ``m_whole_run`` (the figure over every step, where the
experiment scores from a settling time), ``m_se`` (an efficiency's Monte Carlo standard error),
``m_consistent`` (the figure passes its test: inside its band, or at most its ``at_most``); and
the verdicts ``consistent_without_truth`` (every truth-free test passes) and
``consistent_with_truth`` (every test that reads the truth).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from workbench.estimation.metrics import chi2_band
from workbench.metrics.base import Metric, Values

EFFICIENCY_MAX = 1e6
"""An efficiency over this is not given: the bound is then a millionth of the error, a bound whose
information matrix was numerically singular (isam2's map bound gave 7.7e12 on a real log), not a
figure of the estimator."""


def _reduce(how: str, x: np.ndarray) -> float | None:
    x = np.asarray(x, float)
    if how == "sum":
        return float(np.nansum(x))
    if not np.isfinite(x).any():
        return None
    if how == "rms":
        return float(np.sqrt(np.nanmean(np.square(x))))
    if how == "mean":
        return float(np.nanmean(x))
    if how == "max":
        return float(np.nanmax(x))
    return float(np.nanmedian(x))


def counted(v: Values, settle: float | None, m: Metric) -> np.ndarray:
    """The samples a run's figure counts: after ``settle`` where the metric is windowed and the
    samples have times (every sample where none is that late)."""
    if settle is None or not m.window or v.t is None:
        return v.values
    keep = v.t >= settle
    return v.values[keep] if keep.any() else v.values


def run_figure(m: Metric, v: Values | None, settle: float | None = None) -> float | None:
    """A run's figure of one metric (a sweep's row): the reduction of its counted samples."""
    return None if v is None else _reduce(m.reduce, counted(v, settle, m))


def _over_runs(m: Metric, per_run: list[Values], settle: float | None) -> tuple[float | None, list]:
    """The figure over runs and the runs' own figures."""
    figures = [run_figure(m, v, settle) for v in per_run]
    if m.across == "pooled":
        return _reduce(m.reduce, np.concatenate([counted(v, settle, m) for v in per_run])), figures
    x = np.array([np.nan if f is None else f for f in figures], float)
    value = float(np.sum(x)) if m.across == "sum" else float(np.mean(x))
    return (value if np.isfinite(value) else None), figures


def statistics(metrics: Iterable[Metric], runs: list[Mapping[str, Mapping[str, Values]]],
               settle: float | None = None) -> dict[str, dict[str, Any]]:
    """The figures over runs of every metric for every estimator, as the metrics JSON's keys
    (see the module's text): ``runs`` is each run's estimator -> metric -> :class:`Values`;
    ``settle``: the experiment's settling time (the figures count the steps after it, and each
    windowed time series also gives ``<m>_whole_run``), ``None`` where it has none."""
    metrics = list(metrics)
    names = list(dict.fromkeys(n for r in runs for n in r))
    out: dict[str, dict[str, Any]] = {}
    for name in names:
        entry: dict[str, Any] = {}
        figures: dict[str, list] = {}
        for m in metrics:
            if m.efficiency is not None:
                continue
            per_run = [r[name][m.name] for r in runs if name in r and m.name in r[name]]
            if not per_run:
                continue
            entry[m.name], figures[m.name] = _over_runs(m, per_run, settle)
            if m.across == "mean":
                x = np.array([np.nan if f is None else f for f in figures[m.name]], float)
                entry[f"{m.name}_std"] = float(np.std(x)) if np.isfinite(x).all() else None
            timed = all(v.t is not None for v in per_run)
            if settle is not None and m.window and timed:
                entry[f"{m.name}_whole_run"] = _over_runs(m, per_run, None)[0]
            dof = m.dimension or (per_run[0].dof if m.dimension == 0 else None)
            if dof:
                # the band of the figure: a mean over the runs' (correlated) steps counts the runs; over
                # independent samples (a consistent filter's NIS: Bar-Shalom 5.4.2) every sample
                n = (sum(int(np.isfinite(counted(v, settle, m)).sum()) for v in per_run) if m.independent
                     else len(per_run))
                lo, hi = chi2_band(dof, max(n, 1))
                entry[f"{m.name}_band"] = [lo, hi]
                if entry[m.name] is not None:
                    entry[f"{m.name}_consistent"] = bool(lo <= entry[m.name] <= hi)
                curve = _curve(m, per_run)
                if curve is not None:  # each step's mean over the runs, against the band for that many
                    t, c = curve
                    lo, hi = chi2_band(dof, len(per_run))
                    keep = t >= settle if settle is not None and m.window else np.ones(len(t), bool)
                    keep = keep if keep.any() else np.ones(len(t), bool)
                    inside = (c[keep] >= lo) & (c[keep] <= hi)
                    entry[f"{m.name}_inside_band"] = float(np.mean(inside)) if np.isfinite(c[keep]).any() else None
        for m in metrics:
            if m.at_most is not None and entry.get(m.name) is not None:
                entry[f"{m.name}_consistent"] = bool(entry[m.name] <= m.at_most)
        for free, key in ((True, "consistent_without_truth"), (False, "consistent_with_truth")):
            tests = [entry[f"{m.name}_consistent"] for m in metrics
                     if m.truth_free == free and entry.get(f"{m.name}_consistent") is not None]
            if tests:
                entry[key] = all(tests)
        for m in metrics:
            if m.efficiency is None:
                continue
            pairs = [(r[name][m.efficiency[0]], r[name][m.efficiency[1]]) for r in runs
                     if name in r and all(k in r[name] for k in m.efficiency[:2])]
            if not pairs:
                continue
            parts = metrics_by(metrics, m.efficiency)
            entry[m.name] = _efficiency(pairs, settle, parts)
            if entry[m.name] is None and entry.get(m.efficiency[0]) is not None:
                entry[f"{m.name}_note"] = ("no efficiency: its bound is not finite, or near zero (under "
                                           f"1/{EFFICIENCY_MAX:.0e} of the error: a numerical failure of the bound)")
            mse = [x for x in (_mean_square(counted(e, settle, parts[0])) for e, _ in pairs) if x is not None]
            if entry[m.name] is not None and len(mse) > 1 and np.mean(mse) > 0:
                sq = np.array(mse)  # the runs' mean squared errors: the delta method's spread of the ratio
                entry[f"{m.name}_se"] = float(entry[m.name] * 0.5 * sq.std(ddof=1) / (np.sqrt(len(sq)) * sq.mean()))
            if settle is not None and m.window and all(v.t is not None for pair in pairs for v in pair):
                entry[f"{m.name}_whole_run"] = _efficiency(pairs, None, parts)
        out[name] = entry
    return out


def metrics_by(metrics: Iterable[Metric], names: Iterable[Any]) -> list[Any]:
    """The metrics named (an efficiency's scale, a number, passed through)."""
    known = {m.name: m for m in metrics}
    return [known[n] if isinstance(n, str) else n for n in names]


def _mean_square(x: np.ndarray) -> float | None:
    return float(np.nanmean(np.square(x))) if np.isfinite(x).any() else None


def _efficiency(pairs: list[tuple[Values, Values]], settle: float | None, parts: list[Metric]) -> float | None:
    """The RMS of the errors' samples over the RMS of the bounds' (counted as each metric counts
    them), over every run given."""
    err = _mean_square(np.concatenate([counted(e, settle, parts[0]) for e, _ in pairs]))
    if err is not None and len(parts) > 2:
        err *= parts[2] ** 2
    bound = _mean_square(np.concatenate([counted(b, settle, parts[1]) for _, b in pairs]))
    if err is None or bound is None or not np.isfinite(bound) or bound <= 0:
        return None
    eff = float(np.sqrt(err) / np.sqrt(bound))
    return eff if eff <= EFFICIENCY_MAX else None


def run_rows(metrics: Iterable[Metric], run: Mapping[str, Mapping[str, Values]], settle: float | None = None
             ) -> dict[str, dict[str, float]]:
    """One run's figures per estimator, estimator -> metric -> value (NaN where none): a sweep's rows."""
    metrics = list(metrics)
    out: dict[str, dict[str, float]] = {}
    for name, row in run.items():
        figures = {m.name: run_figure(m, row[m.name], settle) for m in metrics
                   if m.efficiency is None and m.name in row}
        for m in metrics:
            if m.efficiency is not None and all(k in row for k in m.efficiency[:2]):
                figures[m.name] = _efficiency([(row[m.efficiency[0]], row[m.efficiency[1]])], settle,
                                              metrics_by(metrics, m.efficiency))
        out[name] = {k: float("nan") if v is None else float(v) for k, v in figures.items()}
    return out


def _curve(m: Metric, per_run: list[Values]) -> tuple[np.ndarray, np.ndarray] | None:
    """The metric's value at each step over the runs (their RMS for an error, mean, max or sum
    otherwise), where every run has the same steps."""
    t = per_run[0].t
    if t is None or any(v.t is None or v.t.shape != t.shape for v in per_run):
        return None
    X = np.stack([v.values for v in per_run])
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)  # steps no run has
        if m.reduce == "rms":
            c = np.sqrt(np.nanmean(X**2, axis=0))
        elif m.reduce == "max":
            c = np.nanmax(X, axis=0)
        elif m.reduce == "sum":
            c = np.nansum(X, axis=0)
        elif m.reduce == "median":
            c = np.nanmedian(X, axis=0)
        else:
            c = np.nanmean(X, axis=0)
    return t, c


def curves(m: Metric, runs: list[Mapping[str, Mapping[str, Values]]]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The recording's curve of one metric over runs, per estimator that has it (its times and
    values): :func:`_curve` of each; empty where the metric has no time series."""
    t, out = np.zeros(0), {}
    names = list(dict.fromkeys(n for r in runs for n in r))
    for name in names:
        per_run = [r[name][m.name] for r in runs if name in r and m.name in r[name]]
        c = _curve(m, per_run) if per_run else None
        if c is not None:
            t, out[name] = c[0], c[1]
    return t, out


# --- the metrics JSON: one shape, and the keys it had before -----------------------------------------

def merge(stats: dict, metrics: Iterable[Metric], figures: Mapping[str, Mapping[str, Any]], runs: int) -> dict:
    """The metrics' figures into the metrics JSON: each estimator's entry gains its keys, and
    ``metric_table`` describes every metric (unit, dimension and band for ``runs`` runs, how it reduces)."""
    entries = stats.setdefault("estimators", {})
    for name, fig in figures.items():
        entries.setdefault(name, {}).update(fig)
    stats["metric_table"] = {m.name: m.describe(runs) for m in metrics}
    return stats


def add_renamed(stats: dict, renamed: Mapping[str, str]) -> dict:
    """Keep the keys a release renamed readable for one release: each old key (a dotted path in
    an estimator's entry, or ``/`` then a dotted path from the top) set to the value at its new
    key, where that exists. ``renamed`` maps old -> new in the same notation."""
    for old, new in renamed.items():
        if old.startswith("/"):
            value = _get(stats, new.lstrip("/"))
            if value is not _MISSING:
                _set(stats, old[1:], value)
            continue
        for entry in stats.get("estimators", {}).values():
            value = _get(entry, new)
            if value is not _MISSING:
                _set(entry, old, value)
    return stats


def upgrade(stats: dict, renamed: Mapping[str, str]) -> dict:
    """The other way: a metrics JSON written before a rename, its new keys filled from the old
    (so a table or a comparison reads it as it reads a new one)."""
    return add_renamed(stats, {new: old for old, new in renamed.items()})


_MISSING = object()


def _get(d: Any, path: str) -> Any:
    for part in path.split("."):
        if not isinstance(d, dict) or part not in d:
            return _MISSING
        d = d[part]
    return d


def _set(d: dict, path: str, value: Any) -> None:
    *parents, last = path.split(".")
    for part in parents:
        d = d.setdefault(part, {})
    if last not in d:
        d[last] = value
