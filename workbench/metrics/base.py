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

Everything else is derived from that one shape, the same for every experiment (:mod:`.figures`:
the figures over runs as the metrics JSON's keys, a sweep's rows, the recording's curves); an
experiment declares which metrics
apply (its package's ``metrics.py``: ``METRICS``), a researcher adds one as a ``module:function``
or ``file.py:function`` spec (``--add-metrics``) or an installed entry point of the group
``workbench.metrics`` (named ``<name>`` for every experiment, ``<experiment>.<name>`` for one),
and it appears in the table, the metrics JSON (``estimators.<name>.<metric>``), the sweeps and
the recording of every experiment it applies to.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import re
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
    their times ``t (n,)`` (seconds of the run); NaN where there is none. ``dof``: each sample's
    chi-square degrees of freedom where they are the estimate's to say (a NIS: the measurement's
    dimension), beside a metric with ``dimension=0``."""

    values: np.ndarray
    t: np.ndarray | None = None
    dof: int | None = None  # the chi-square degrees of freedom of each sample, where the metric leaves it open

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


@functools.lru_cache(maxsize=512)
def _takes_context(fn: Callable) -> bool:
    """Whether a metric's function takes the context as a third argument (asked once per function:
    ``inspect.signature`` costs 25 us, and a run asks it of every metric and estimator)."""
    try:
        return len(inspect.signature(fn).parameters) >= 3
    except (TypeError, ValueError):
        return False


@dataclass(frozen=True, eq=False)
class Metric:
    """One metric: its function and how its samples read and combine (see the module's text)."""

    name: str
    function: Callable[..., Values | None] | None
    unit: str
    description: str
    reduce: str = "rms"
    across: str = "pooled"
    dimension: int | None = None   # chi-square degrees of freedom of each sample (NEES, NIS); 0: the samples say
    window: bool = True            # the run's figure counts only the steps after the experiment's settling time
    independent: bool = False      # its samples are independent (a consistent filter's NIS): its band is for them all
    at_most: float | None = None   # a figure at most this passes its test (the whiteness test's share of lags)
    truth_free: bool = False       # it reads no truth: it judges an estimator on a log without one
    efficiency: tuple | None = None  # (error, bound[, scale]): the RMS of one's samples (times scale) over the other's
    label: str = ""                # a short column title, with its unit (default: the name and the unit)
    fmt: str = ".2f"               # how the table writes it
    source: str = "built-in"
    ref: str | None = None         # how another process finds it again (a spec), plugins only
    experiments: tuple[str, ...] = ()  # the experiments it applies to (empty: any whose estimates it takes)
    evidence: bool = False         # normalised squared residuals (chi-square, their dof) the diagnosis may read

    def __post_init__(self) -> None:
        if not NAME.fullmatch(self.name):
            raise WorkbenchError(f"metric name {self.name!r}: a letter, then letters, digits and _ only")
        if self.reduce not in REDUCTIONS or self.across not in ACROSS:
            raise WorkbenchError(f"metric {self.name}: reduce is one of {', '.join(REDUCTIONS)}, across one of "
                                 f"{', '.join(ACROSS)}")

    @property
    def title(self) -> str:
        """A table's column title: the label as given (with its unit), else the name and the unit."""
        return self.label or self.name + (f" {self.unit}" if self.unit else "")

    def __call__(self, data: Any, estimate: Any, ctx: MetricContext) -> Values | None:
        fn = self.function
        out = fn(data, estimate, ctx) if _takes_context(fn) else fn(data, estimate)
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
        elif self.dimension == 0:
            out["dimension"] = "each estimate's own (its samples' dof)"
        if self.efficiency:
            out["efficiency"] = list(self.efficiency[:2])
        if self.at_most is not None:
            out["at_most"] = self.at_most
        out["truth_free"] = self.truth_free
        return out

    def __reduce__(self):
        if self.ref is not None:
            return find, (self.ref, self.name)
        return Metric, tuple(getattr(self, f.name) for f in dataclasses.fields(self))


def metric(*, name: str | None = None, unit: str = "", description: str | None = None, reduce: str = "rms",
           across: str = "pooled", dimension: int | None = None, window: bool = True, independent: bool = False,
           at_most: float | None = None, truth_free: bool = False, label: str = "", fmt: str = ".2f",
           experiments: Iterable[str] = ()) -> Callable:
    """Decorate a plugin metric function with how its samples read and combine (the defaults: an
    error in ``unit`` whose figure is its RMS over the steps and the runs)."""

    def mark(fn: Callable) -> Callable:
        fn.__workbench_metric__ = {"name": name, "unit": unit, "description": description, "reduce": reduce,
                                   "across": across, "dimension": dimension, "window": window,
                                   "independent": independent, "at_most": at_most, "truth_free": truth_free,
                                   "label": label,
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
    (``module:function`` / ``file.py:function``, optionally ``name=spec``), found as an estimator
    is (:func:`workbench.loading.resolve`); ``local:<name>`` a function this process was handed."""
    if isinstance(item, str) and item.strip().startswith("local:") and item.strip()[6:] in _LOCAL:
        return _LOCAL[item.strip()[6:]]
    plugins = installed(experiment) if experiment else {}

    def unknown(text: str) -> str:
        return (f"unknown metric {text!r}: give module:function or file.py:function"
                + (f" (installed: {', '.join(plugins)})" if plugins else ""))

    found = loading.resolve(item, "metric", Metric, {}, plugins, unknown, NAME.pattern)
    name = found.name
    if found.how == "row":
        return item
    if found.how == "function":
        ref = loading.python_ref(item)
        m = from_function(item, None, ref, "python")
        if ref is None:
            _LOCAL[m.name] = m
            m = dataclasses.replace(m, ref=f"local:{m.name}")
        return m
    if found.how == "installed":
        return dataclasses.replace(from_function(found.value, name or found.key, None,
                                                 f"entry point {found.entry_point.name}"), ref=found.key)
    ref = loading.spec_ref(found.key)
    return from_function(found.value, name, f"{name}={ref}" if name else ref, found.key)


def spec(item: Any, experiment: str = "") -> str:
    """What selects a metric plugin again (in a config, a worker): its spec, installed name or
    ``local:<name>``; a one-line error for one that cannot be loaded."""
    if isinstance(item, str):
        one(item, experiment)  # loads, or says why not
        return item.strip()
    m = one(item, experiment)
    return m.ref or m.name


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
