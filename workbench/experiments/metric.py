"""One metric interface for every experiment (the model: evo's ``core/metrics.py``).

A **metric** is a named function of a run's dataset and one estimate,
``fn(data, estimate) -> Values`` (``fn(data, estimate, ctx)`` where it wants the
:class:`MetricContext`), returning its samples: per step (with their times: a time series,
drawn as a curve in the recording), per item (a landmark) or one value for the run; ``None``
where it does not apply to that estimate (no covariance, no map). Its :class:`Metric` row
says what the samples are: the unit, a line of description, the chi-square dimension where the
samples are normalised squared errors (NEES, NIS: its band follows), how a run's samples reduce
to the run's figure (``reduce``: rms, mean, max, median, sum) and how runs combine
(``across``: ``pooled``, the reduction over every run's samples at once; ``mean``, the mean of
the runs' figures with their spread; ``sum``). An efficiency metric is the RMS of one metric's
samples (an error) over the RMS of another's (its Cramér-Rao bound) at every level.

Everything else is derived from that one shape, by this module, the same for every experiment
(:func:`statistics`: the figures over runs; :func:`columns`: the JSON keys; :func:`run_rows`:
a sweep's rows; :func:`curves`: the recording's curves); an experiment declares which metrics
apply (its package's ``metrics.py``: ``METRICS``), a researcher adds one as a ``module:function``
or ``file.py:function`` spec (``--add-metrics``) or an installed entry point of the group
``workbench.metrics`` (named ``<name>`` for every experiment, ``<experiment>.<name>`` for one),
and it appears in the table, the metrics JSON (``estimators.<name>.<metric>``), the sweeps and
the recording of every experiment it applies to.

Keys of the metrics JSON per estimator and metric ``m``: ``m`` (the figure over runs),
``m_std`` (the spread of the runs' figures, ``across="mean"``), ``m_band`` (the 95 % chi-square
band of the figure, where it has a dimension), ``m_inside_band`` (the share of scored steps where
the mean over runs is inside that band), ``m_whole_run`` (the figure over every step, where the
experiment scores from a settling time), ``m_se`` (an efficiency's Monte Carlo standard error).
"""

from __future__ import annotations

import dataclasses
import inspect
import re
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from workbench import loading
from workbench.errors import WorkbenchError
from workbench.estimation.metrics import chi2_band

GROUP = "workbench.metrics"
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
REDUCTIONS = ("rms", "mean", "max", "median", "sum")
ACROSS = ("pooled", "mean", "sum")


@dataclass
class Values:
    """A metric's samples for one estimate on one run: ``values (n,)`` and, for a time series,
    their times ``t (n,)`` (seconds of the run); NaN where there is none."""

    values: np.ndarray
    t: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.values = np.atleast_1d(np.asarray(self.values, float)).ravel()
        if self.t is not None:
            self.t = np.asarray(self.t, float).ravel()
            if self.t.shape != self.values.shape:
                raise WorkbenchError(f"a metric's times {self.t.shape} and values {self.values.shape} differ")


@dataclass
class MetricContext:
    """What a metric gets beside the dataset and the estimate: the run's config, its number, the
    estimator's table row, every estimate of the run (a reference to compare with), and
    ``shared(key, make)``: a product several metrics use (an alignment, a bound), made once a run."""

    cfg: Any
    run: int = 0
    name: str = ""                 # the estimate's estimator's name
    estimator: Any = None          # the estimator's table row (its name, colour, whether causal, its delay)
    estimates: Mapping[str, Any] = field(default_factory=dict)
    estimators: Mapping[str, Any] = field(default_factory=dict)  # every estimator's table row, by name
    products: Mapping[str, Any] = field(default_factory=dict)  # the estimators' shared products of the run
    cache: dict = field(default_factory=dict)
    result: Any = None             # the run's whole result (its experiment's RunResult)

    def shared(self, key: str, make: Callable[[], Any]) -> Any:
        if key not in self.cache:
            self.cache[key] = make()
        return self.cache[key]


@dataclass(frozen=True, eq=False)
class Metric:
    """One metric: its function and how its samples read and combine (see the module's text)."""

    name: str
    function: Callable[..., Values | None] | None
    unit: str
    description: str
    reduce: str = "rms"
    across: str = "pooled"
    dimension: int | None = None   # chi-square degrees of freedom of each sample (NEES, NIS)
    window: bool = True            # the run's figure counts only the steps after the experiment's settling time
    efficiency: tuple | None = None  # (error, bound[, scale]): the RMS of one's samples (times scale) over the other's
    label: str = ""                # a short column title (default: the name)
    fmt: str = ".2f"               # how the table writes it
    source: str = "built-in"
    ref: str | None = None         # how another process finds it again (a spec), plugins only
    experiments: tuple[str, ...] = ()  # the experiments it applies to (empty: any whose estimates it takes)

    def __post_init__(self) -> None:
        if not NAME.fullmatch(self.name):
            raise WorkbenchError(f"metric name {self.name!r}: a letter, then letters, digits and _ only")
        if self.reduce not in REDUCTIONS or self.across not in ACROSS:
            raise WorkbenchError(f"metric {self.name}: reduce is one of {', '.join(REDUCTIONS)}, across one of "
                                 f"{', '.join(ACROSS)}")

    @property
    def title(self) -> str:
        return (self.label or self.name) + (f" {self.unit}" if self.unit else "")

    def __call__(self, data: Any, estimate: Any, ctx: MetricContext) -> Values | None:
        fn = self.function
        try:
            takes = len(inspect.signature(fn).parameters) >= 3
        except (TypeError, ValueError):
            takes = False
        out = fn(data, estimate, ctx) if takes else fn(data, estimate)
        if out is None or isinstance(out, Values):
            return out
        if isinstance(out, tuple) and len(out) == 2:
            return Values(out[1], out[0])
        return Values(out)

    def describe(self, runs: int) -> dict:
        out = {"unit": self.unit, "description": self.description, "reduce": self.reduce, "across": self.across,
               "source": self.source}
        if self.dimension:
            out["dimension"] = self.dimension
            out["band"] = list(chi2_band(self.dimension, runs))
        if self.efficiency:
            out["efficiency"] = list(self.efficiency[:2])
        return out

    def __reduce__(self):
        if self.ref is not None:
            return find, (self.ref, self.name)
        return Metric, tuple(getattr(self, f.name) for f in dataclasses.fields(self))


def metric(*, name: str | None = None, unit: str = "", description: str | None = None, reduce: str = "rms",
           across: str = "pooled", dimension: int | None = None, window: bool = True, label: str = "",
           fmt: str = ".2f", experiments: Iterable[str] = ()) -> Callable:
    """Decorate a plugin metric function with how its samples read and combine (the defaults: an
    error in ``unit`` whose figure is its RMS over the steps and the runs)."""

    def mark(fn: Callable) -> Callable:
        fn.__workbench_metric__ = {"name": name, "unit": unit, "description": description, "reduce": reduce,
                                   "across": across, "dimension": dimension, "window": window, "label": label,
                                   "fmt": fmt, "experiments": tuple(experiments)}
        return fn

    return mark


# --- naming a metric: built-ins, installed plugins, specs, functions ---------------------------------

_LOCAL: dict[str, Metric] = {}
"""Metrics given as Python functions no other process can import: by name (a forked worker has them)."""


def from_function(fn: Any, name: str | None = None, ref: str | None = None, source: str = "python") -> Metric:
    """A :class:`Metric` from a plugin function and what :func:`metric` attached to it."""
    if isinstance(fn, Metric):
        return fn
    if not callable(fn):
        raise WorkbenchError(f"metric {source} is not a function")
    meta = dict(getattr(fn, "__workbench_metric__", {}))
    name = name or meta.pop("name", None) or getattr(fn, "__name__", "metric")
    meta.pop("name", None)
    doc = (inspect.getdoc(fn) or "").strip().splitlines()
    description = meta.pop("description", None) or (doc[0] if doc else f"{name} (a plugin)")
    return Metric(name, fn, description=description, source=source, ref=ref, **{"unit": "", **meta})


def installed(experiment: str) -> dict:
    """The installed metric plugins that may apply to ``experiment``: entry points named
    ``<name>`` (any experiment) or ``<experiment>.<name>``, by metric name (not yet loaded)."""
    every = loading.entry_points(GROUP)
    return {**{k: ep for k, ep in every.items() if "." not in k},
            **{k.split(".", 1)[1]: ep for k, ep in every.items() if k.startswith(experiment + ".")}}


def one(item: Any, experiment: str = "") -> Metric:
    """One metric plugin: a :class:`Metric`, a function, an installed name, or a spec
    (``module:function`` / ``file.py:function``, optionally ``name=spec``)."""
    if isinstance(item, Metric):
        return item
    if callable(item):
        ref = loading.python_ref(item)
        m = from_function(item, None, ref, "python")
        if ref is None:
            _LOCAL[m.name] = m
            m = dataclasses.replace(m, ref=f"local:{m.name}")
        return m
    text = str(item).strip()
    name = None
    found = re.fullmatch(rf"({NAME.pattern})=(.+)", text)
    if found:
        name, text = found.group(1), found.group(2).strip()
    if text.startswith("local:") and text[6:] in _LOCAL:
        return _LOCAL[text[6:]]
    plugins = installed(experiment) if experiment else {}
    if text in plugins:
        ep = plugins[text]
        obj = loading.load_entry_point(ep, f"metric {text!r}")
        return dataclasses.replace(from_function(obj, name or text, None, f"entry point {ep.name}"), ref=text)
    if ":" not in text:
        raise WorkbenchError(f"unknown metric {text!r}: give module:function or file.py:function"
                             + (f" (installed: {', '.join(plugins)})" if plugins else ""))
    fn = loading.load(text, "metric")
    ref = loading.spec_ref(text)
    return from_function(fn, name, f"{name}={ref}" if name else ref, text)


def find(ref: str, name: str) -> Metric:
    """A plugin metric found again from its ref (in a worker process): unpickling goes here."""
    m = one(ref)
    return m if m.name == name else dataclasses.replace(m, name=name)


def select(builtin: Iterable[Metric], experiment: str, extra: Iterable[Any] = ()) -> list[Metric]:
    """The metrics of a run: the experiment's built-ins, every installed plugin that applies to
    it, and ``extra`` (specs or functions); one-line errors for a name taken twice."""
    out = list(builtin)
    for name, ep in installed(experiment).items():
        m = from_function(loading.load_entry_point(ep, f"metric {name!r}"), name, None, f"entry point {ep.name}")
        out.append(dataclasses.replace(m, ref=name))
    out += [one(x, experiment) for x in extra]
    out = [m for m in out if not m.experiments or experiment in m.experiments]
    names = [m.name for m in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise WorkbenchError(f"metric {twice[0]!r} is defined twice (a plugin's name must not be a built-in's)")
    known = set(names)
    for m in out:
        if m.efficiency and not set(m.efficiency[:2]) <= known:
            raise WorkbenchError(f"metric {m.name} is the efficiency of {', '.join(m.efficiency)}, not all of them "
                                 "metrics here")
    return out


# --- a run: every metric of every estimate ------------------------------------------------------------

def evaluate(metrics: Iterable[Metric], data: Any, estimates: Mapping[str, Any], ctx: MetricContext
             ) -> tuple[dict[str, dict[str, Values]], dict[str, str]]:
    """Every metric's samples for every estimate of a run, estimator -> metric -> :class:`Values`
    (metrics that do not apply left out), and the metrics that failed (``"estimator/metric"`` ->
    one line): a plugin metric that raises costs its own figures, nothing else."""
    out: dict[str, dict[str, Values]] = {}
    failed: dict[str, str] = {}
    for name, est in estimates.items():
        mine = dataclasses.replace(ctx, name=name, estimator=ctx.estimators.get(name))
        row: dict[str, Values] = {}
        for m in metrics:
            if m.efficiency is not None:
                continue
            try:
                v = m(data, est, mine)
            except KeyboardInterrupt:
                raise
            except Exception as exc:
                if m.source == "built-in":
                    raise
                failed[f"{name}/{m.name}"] = f"{type(exc).__name__}: {loading.first_line(exc)}"
                continue
            if v is not None:
                row[m.name] = v
        out[name] = row
    return out, failed


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
            if m.dimension:
                lo, hi = chi2_band(m.dimension, len(per_run))
                entry[f"{m.name}_band"] = [lo, hi]
                curve = _curve(m, per_run)
                if curve is not None:
                    t, c = curve
                    keep = t >= settle if settle is not None and m.window else np.ones(len(t), bool)
                    keep = keep if keep.any() else np.ones(len(t), bool)
                    inside = (c[keep] >= lo) & (c[keep] <= hi)
                    entry[f"{m.name}_inside_band"] = float(np.mean(inside)) if np.isfinite(c[keep]).any() else None
        for m in metrics:
            if m.efficiency is None:
                continue
            pairs = [(r[name][m.efficiency[0]], r[name][m.efficiency[1]]) for r in runs
                     if name in r and all(k in r[name] for k in m.efficiency[:2])]
            if not pairs:
                continue
            parts = metrics_by(metrics, m.efficiency)
            entry[m.name] = _efficiency(pairs, settle, parts)
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
    if err is None or bound is None or bound <= 0:
        return None
    return float(np.sqrt(err) / np.sqrt(bound))


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
