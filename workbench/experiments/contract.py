"""The contract between an experiment and everything that runs it: the CLI, the demo, the
Python API and the sweeps reach an experiment only through its :class:`Experiment`.

An experiment declares its scenarios (each a set of defaults), its command-line options (each
one config field), and its **estimator table**: name -> :class:`Estimator` (how to run it on a
dataset, its colour, a line of description, whether it is causal and whether it gives
covariances). A run flows one way: ``configure -> data -> estimate -> evaluate -> record``.

An experiment is a package ``workbench/experiments/<name>/`` with one module per role, which
:class:`Experiment` calls by name (:meth:`Experiment.role`), and one line in the registry
(:mod:`workbench.experiments`):

=================  ==========================================================================
``config.py``      the config dataclass (fields ``scenario``, ``seed``, ``runs``,
                   ``estimators``; ``validate()``, ``to_json()``; scenario-dependent fields
                   declared with :func:`by_scenario`, filled by :func:`apply_scenario` in
                   ``__post_init__``), ``SCENARIOS`` (name -> :class:`Scenario`), ``OPTIONS``
``scenario.py``    the public dataset type (what an estimator reads; truth for evaluation only)
``estimate.py``    the public estimate type, and ``check(estimate, data, cfg, estimator)``
``estimators.py``  ``TABLE``: the built-in estimators (:func:`table`)
``run.py``         ``make_data(cfg, run)``: run k's dataset; ``run_once(cfg, run, estimators,
                   record, threads)``: that dataset and every estimator on it
                   (:func:`estimate_all`), a result with ``data``, ``estimates``,
                   ``estimators``, ``failed``; optionally ``run_count(cfg)`` (runs a config
                   makes, if not ``cfg.runs``) and ``grid_values`` (a sweep's values expanded)
``evaluate.py``    ``summarise(result, cfg, run)``: a run's errors and summary (picklable,
                   with ``run`` and ``failed``); ``statistics(cfg, summaries, label)``;
                   ``run_metrics(summary, cfg)`` and ``RUN_METRICS``: a run's figures (sweeps)
``report.py``      ``table(stats)``: the results table (markdown)
``record.py``      ``layout(first, summaries)``: the default blueprint; ``record_run(rec, first,
                   summary)``: run 0 drawn from ``first`` and its evaluation (streamed live as
                   soon as run 0 is done); ``record_runs(rec, first, summaries, table)``: the
                   curves over runs and the table
``experiment.py``  ``EXPERIMENT``: an :class:`Experiment` subclass declaring the above (name,
                   description, config type, scenarios, options, data and estimate types,
                   demo steps) and any hooks for extra options (exports, an alternative run)
=================  ==========================================================================

An estimator is a function ``(data, cfg) -> Estimate`` of the experiment's public dataset and
estimate types (``(data, cfg, ctx)`` where it wants the :class:`RunContext`); a researcher's own
estimator is the same kind of function, and goes everywhere a built-in goes.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import os
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from workbench.errors import WorkbenchError

Color = tuple[int, int, int]


# --- scenarios and their defaults ------------------------------------------------------------------

@dataclass(frozen=True)
class Scenario:
    """A named set of defaults. ``defaults`` maps config fields to values; ``real_data``: it
    reads data that may be absent (the demo skips it then, and only then)."""

    name: str
    description: str
    defaults: Mapping[str, Any] = field(default_factory=dict)
    real_data: bool = False


def by_scenario(base: Any) -> Any:
    """A config field whose default depends on the scenario: ``base`` unless the scenario's
    :class:`Scenario` defaults name another value. It reads as ``None`` until the config's
    ``__post_init__`` calls :func:`apply_scenario`, which fills it (the one place it happens)."""
    return field(default=None, metadata={"base": base})


def scenario_fields(config_type: type) -> dict[str, Any]:
    """The fields declared with :func:`by_scenario` and their base defaults."""
    return {f.name: f.metadata["base"] for f in dataclasses.fields(config_type) if "base" in f.metadata}


def apply_scenario(cfg: Any, scenarios: Mapping[str, Scenario]) -> None:
    """Fill every :func:`by_scenario` field left ``None`` from ``cfg.scenario``'s defaults (or the
    base). An unknown scenario is a one-line error here, so a config never exists with one."""
    if cfg.scenario not in scenarios:
        raise WorkbenchError(f"unknown scenario {cfg.scenario!r}; choose one of {', '.join(scenarios)}")
    defaults = scenarios[cfg.scenario].defaults
    for name, base in scenario_fields(type(cfg)).items():
        if getattr(cfg, name) is None:
            setattr(cfg, name, defaults.get(name, base))


def default_text(config_type: type, scenarios: Mapping[str, Scenario], name: str) -> str:
    """How a field's default reads in ``--help``: ``[3]``, or ``[3; ais 20]`` where a scenario differs."""
    fields = {f.name: f for f in dataclasses.fields(config_type)}
    f = fields[name]
    if "base" in f.metadata:
        base = f.metadata["base"]
        other = [f"{s} {_show(sc.defaults[name])}" for s, sc in scenarios.items()
                 if name in sc.defaults and sc.defaults[name] != base]
        return "[" + "; ".join([_show(base), *other]) + "]"
    if f.default is not dataclasses.MISSING:
        return f"[{_show(f.default)}]" if f.default is not None else ""
    return ""


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, tuple) and len(value) == 2 and all(isinstance(v, int) for v in value):
        return f"{value[0]}x{value[1]}"  # an image size
    if isinstance(value, tuple):
        return ",".join(map(str, value))
    return f"{value:g}" if isinstance(value, float) else str(value)


@dataclass(frozen=True)
class Demo:
    """One step of ``workbench demo``: a scenario with overrides, written as ``<name>.rrd`` /
    ``<name>.json``, with at most ``max_runs`` of the demo's runs."""

    name: str
    scenario: str
    overrides: Mapping[str, Any] = field(default_factory=dict)
    max_runs: int | None = None
    estimators: str | None = None


@dataclass(frozen=True)
class Preset:
    """A named sweep: ``grid`` (config field -> values) on ``scenario`` with ``overrides``."""

    name: str
    description: str
    grid: Mapping[str, tuple]
    scenario: str | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    estimators: str | None = None
    report: str | None = None  # "module:function(table, folder, definition) -> paths": its own report too


# --- command-line options --------------------------------------------------------------------------

@dataclass(frozen=True)
class Option:
    """One command-line option of an experiment, setting one config field (or, for an
    experiment's ``extras``, one value handed to its hooks).

    ``type`` is what the command line parses (``str`` for values ``parse`` turns into the
    field's type); ``flag`` defaults to ``--field-name``; ``switch`` is ``"--on/--off"`` for a
    boolean; ``sets`` names the config fields it sets where that is not ``field`` alone.
    Every option defaults to "not given", so the scenario's default applies."""

    field: str
    help: str
    type: type = float
    flag: str | None = None
    parse: Callable[[Any], Any] | None = None
    switch: str | None = None
    sets: tuple[str, ...] = ()

    @property
    def fields(self) -> tuple[str, ...]:
        return self.sets or (self.field,)

    @property
    def flags(self) -> tuple[str, ...]:
        if self.switch:
            return (self.switch,)
        return (self.flag or "--" + self.field.replace("_", "-"),)

    def described(self, config_type: type, scenarios: Mapping[str, Scenario]) -> str:
        """The help text with the default appended (``[3; ais 20]``), where the help gives none."""
        if "[" in self.help or self.fields[0] not in {f.name for f in dataclasses.fields(config_type)}:
            return self.help
        return f"{self.help} {default_text(config_type, scenarios, self.fields[0])}".strip()

    def value(self, given: Any) -> Any:
        """The config value of what the command line parsed (a one-line error if ``parse`` fails)."""
        if given is not None and self.type is Path:
            # typed as text on the command line (typer would make '' the current folder, '.')
            if not str(given).strip():
                raise WorkbenchError(f"{self.flags[0]} needs a path, got ''")
            given = Path(str(given))
        if given is None or self.parse is None:
            return given
        try:
            return self.parse(given)
        except (ValueError, TypeError) as exc:
            raise WorkbenchError(f"{self.flags[0]}: {exc}") from None


def split_list(text: str) -> tuple[str, ...]:
    """``"a, b,c"`` -> ``("a", "b", "c")``."""
    return tuple(p.strip() for p in str(text).split(",") if p.strip())


# --- estimators ------------------------------------------------------------------------------------

class EstimateError(ValueError):
    """An estimate that breaks its type's contract (shape, NaNs, a covariance not PSD)."""


@dataclass
class RunContext:
    """What a built-in (or a plugin that asks for it) gets beside the data and the config.

    ``record``: this run is the recorded one (compute what only the recording draws: traces,
    covariances at every step). ``shared(key, make)``: a product several estimators use (a
    factor set, a search), made once per run; each estimator using it is charged its time.
    """

    run: int = 0
    record: bool = False
    threads: int = 1
    cache: dict = field(default_factory=dict)
    _fresh: float = 0.0
    _used: set = field(default_factory=set)

    def shared(self, key: str, make: Callable[[], Any]) -> Any:
        if key not in self.cache:
            t0 = time.perf_counter()
            value = make()
            cost = time.perf_counter() - t0
            self.cache[key] = (value, cost)
            self._fresh += cost
        self._used.add(key)
        return self.cache[key][0]

    def get(self, key: str, default: Any = None) -> Any:
        """A shared product if some estimator made it (for evaluation and the recording)."""
        return self.cache[key][0] if key in self.cache else default


@dataclass(eq=False)
class Estimator:
    """One row of an estimator table.

    ``run`` is ``(data, cfg)`` or, if it takes a third argument, ``(data, cfg, ctx)``; a
    ``"module:function"`` string is imported when first run (a built-in's row costs no
    import). ``ref`` finds it again in another process (its name, or its ``module:function`` /
    ``file.py:function`` spec); ``source`` says where it came from (``built-in``, an entry
    point, a spec, a Python object)."""

    name: str
    run: Callable[..., Any]
    color: Color
    description: str
    causal: bool
    covariances: bool
    experiment: str = ""
    source: str = "built-in"
    ref: str | None = None
    indefinite: str = ""  # why its covariance may be indefinite (then not checked to be PSD): a known flaw
    lag: float | None = None  # seconds of data after step k its estimate of k uses (None: 0 if causal, else all)

    @property
    def delay(self) -> float:
        """The seconds of data after a step its estimate of that step uses: 0 for a filter, ``inf``
        for a smoother of the whole run, the lag of a fixed-lag smoother. Which Cramér-Rao bound
        it is held to follows: filtering, smoothing, or the bound of that lag."""
        if self.lag is not None:
            return float(self.lag)
        return 0.0 if self.causal else float("inf")

    @property
    def builtin(self) -> bool:
        return self.source == "built-in"

    @property
    def spec(self) -> str:
        """What selects it again (in a config, a sweep's task): its name, or ``name=ref``."""
        return self.name if self.ref in (None, self.name) else f"{self.name}={self.ref}"

    def function(self) -> Callable[..., Any]:
        """The runner; a ``"module:function"`` string is imported when first needed."""
        if isinstance(self.run, str):
            from workbench.experiments.plugins import load

            self.run = load(self.run)
        return self.run

    @property
    def takes_context(self) -> bool:
        try:
            return len(inspect.signature(self.function()).parameters) >= 3
        except (TypeError, ValueError):
            return False

    def __call__(self, data: Any, cfg: Any, ctx: RunContext) -> Any:
        fn = self.function()
        return fn(data, cfg, ctx) if self.takes_context else fn(data, cfg)

    def __reduce__(self):
        # sent to a worker process as how to find it, not as its code (a file-loaded plugin
        # or an entry point loads again there); a Python object without a ref by reference
        if self.ref is not None:
            from workbench.experiments import plugins

            return plugins.find, (self.experiment, self.ref, self.name, self.color)
        return Estimator, (self.name, self.run, self.color, self.description, self.causal, self.covariances,
                           self.experiment, self.source, self.ref, self.indefinite, self.lag)

    def describe(self) -> dict:
        out = {"description": self.description, "causal": self.causal, "covariances": self.covariances,
               "source": self.source, "color": list(self.color)}
        if self.indefinite:
            out["indefinite_covariance"] = self.indefinite
        if self.lag is not None:
            out["lag_seconds"] = self.lag
        return out


def table(experiment: str, *rows: Estimator) -> dict[str, Estimator]:
    """An experiment's built-in estimator table, name -> row, in the order given."""
    return {e.name: dataclasses.replace(e, experiment=experiment, ref=e.name) for e in rows}


def estimate_all(estimators: Iterable[Estimator], data: Any, cfg: Any, ctx: RunContext,
                 check: Callable[[Any, Any, Any, Estimator], Any]) -> tuple[dict[str, Any], dict[str, str]]:
    """Every estimator on the same data, in order, each timed and checked.

    Returns the estimates by name and the failures (name -> one line): an estimator that
    raises or whose estimate fails ``check`` is left out, the others go on. Each estimate's
    ``seconds`` is its own time plus that of the shared products it used
    (:meth:`RunContext.shared`). ``WORKBENCH_DEBUG=1`` re-raises instead.
    """
    out: dict[str, Any] = {}
    failures: dict[str, str] = {}
    for est in estimators:
        ctx._fresh, ctx._used = 0.0, set()
        t0 = time.perf_counter()
        try:
            result = est(data, cfg, ctx)
            result = check(result, data, cfg, est)
        except KeyboardInterrupt:
            raise
        except Exception as exc:
            if os.environ.get("WORKBENCH_DEBUG"):
                raise
            failures[est.name] = one_line(exc)
            continue
        own = time.perf_counter() - t0 - ctx._fresh
        result.seconds = own + sum(ctx.cache[k][1] for k in ctx._used)
        out[est.name] = result
    return out, failures


def one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    first = text[0] if text else ""
    return f"{type(exc).__name__}: {first}" if not isinstance(exc, (EstimateError, WorkbenchError)) else first


# --- checks an estimate must pass (shared by the experiments' ``check``) ------------------------------

def as_array(value: Any, what: str, shape: tuple[int | None, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape`` (None: any length), else :class:`EstimateError`."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise EstimateError(f"{what} is not an array of numbers") from None
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape, strict=True)):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise EstimateError(f"{what} has shape {a.shape}, expected {want}")
    if np.isinf(a).any():
        raise EstimateError(f"{what} has infinite values")
    return a


def whole_rows(a: np.ndarray, what: str, axes: int = 1, allow_empty: bool = True) -> np.ndarray:
    """Each row (the last ``axes`` axes) is all finite or all NaN ("no estimate at this step");
    a partly-NaN row, or NaN everywhere (unless ``allow_empty``), is an :class:`EstimateError`.
    Returns the rows' finite mask."""
    inner = tuple(range(a.ndim - axes, a.ndim))
    nan = np.isnan(a)
    some, every = nan.any(axis=inner), nan.all(axis=inner)
    if (some & ~every).any():
        k = int(np.flatnonzero(some & ~every)[0])
        raise EstimateError(f"{what} is partly NaN at row {k} (a row is all numbers or all NaN)")
    if not allow_empty and every.all():
        raise EstimateError(f"{what} is NaN everywhere")
    return ~every


def psd(cov: np.ndarray, what: str, rows: np.ndarray | None = None, estimator: Estimator | None = None) -> None:
    """Symmetric positive semi-definite (to round-off) wherever finite; rows that must be
    finite (``rows`` True) are checked to be. An estimator whose table row says why its
    covariance may be indefinite (``indefinite``, a known flaw such as the omni paper's
    augmentation) is not held to PSD."""
    cov = np.asarray(cov, float)
    finite = np.isfinite(cov).all(axis=(-1, -2))
    if rows is not None and (rows & ~finite).any():
        k = int(np.flatnonzero(rows & ~finite)[0])
        raise EstimateError(f"{what} is not finite at row {k}, where the estimate is")
    if estimator is not None and estimator.indefinite:
        return
    c = cov[finite]
    if not len(c):
        return
    scale = np.maximum(np.abs(c).max(axis=(-1, -2)), 1e-300)
    asym = np.abs(c - np.swapaxes(c, -1, -2)).max(axis=(-1, -2)) / scale
    if (asym > 1e-6).any():
        k = int(np.flatnonzero(finite)[np.argmax(asym > 1e-6)])
        raise EstimateError(f"{what} is not symmetric at row {k}")
    low = np.linalg.eigvalsh((c + np.swapaxes(c, -1, -2)) / 2).min(axis=-1)
    if (low < -1e-9 * scale).any():
        k = int(np.flatnonzero(finite)[np.argmax(low < -1e-9 * scale)])
        raise EstimateError(f"{what} is not positive semi-definite at row {k} (eigenvalue {low.min():.3g})")


# --- the experiment --------------------------------------------------------------------------------

class Experiment:
    """The base every experiment fills; the one object the CLI, demo, API and sweeps use.

    Subclasses set the class attributes (in their package's ``experiment.py``); the flow's
    methods go to the package's role modules by name (:meth:`role`), and the base gives the
    configuration and the estimator selection, the same for all.
    """

    name: str = ""
    description: str = ""
    config_type: type = object
    scenarios: Mapping[str, Scenario] = {}
    options: tuple[Option, ...] = ()
    extras: tuple[Option, ...] = ()
    required: tuple[str, ...] = ()     # estimators every run has (evaluation needs them)
    demo: tuple[Demo, ...] = ()        # what `workbench demo` runs of it
    presets: tuple[Preset, ...] = ()   # named sweeps (`workbench sweep --preset NAME`)
    headline: tuple[str, ...] = ()     # the per-run metrics a sweep's report leads with
    paper_notes: Mapping[str, str] = {}  # metric -> the paper's figure, shown beside a sweep's table
    compared: tuple[str, ...] = ()     # time plots (view origins) whose curves `workbench compare` differences
    data_type: type = object           # the public dataset an estimator reads
    estimate_type: type = object       # the public estimate an estimator returns

    def role(self, name: str) -> Any:
        """The experiment package's module for a role (``estimators``, ``run``, ``evaluate``,
        ``report``, ``record``, ``estimate``), imported when first needed: the methods below
        call them by these names, so an experiment's ``experiment.py`` only declares."""
        package = type(self).__module__.rpartition(".")[0]
        return importlib.import_module(f"{package}.{name}")

    @property
    def estimators(self) -> dict[str, Estimator]:
        """The built-in estimator table, name -> :class:`Estimator`, in the order they run."""
        return self.role("estimators").TABLE

    @property
    def default_estimators(self) -> tuple[str, ...]:
        return tuple(self.estimators)

    # --- configure
    def configure(self, scenario: str | None = None, **overrides: Any) -> Any:
        """The config of ``scenario`` (default: the first) with ``overrides`` on top; ``None``
        means "not given" (the scenario's default). Unknown names are a one-line error."""
        names = {f.name for f in dataclasses.fields(self.config_type)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise WorkbenchError(f"{self.name} has no setting {', '.join(unknown)}; "
                                 f"see `workbench {self.name} --help`")
        given = {k: v for k, v in overrides.items() if v is not None}
        return self.config_type(scenario=scenario or next(iter(self.scenarios)), **given)

    def validate(self, cfg: Any) -> Any:
        """``cfg.validate()`` (the experiment's own ranges), then the checks every experiment
        shares (:mod:`workbench.experiments.limits`: finite numbers of sane size, seed and runs in
        range, the memory the run will need); the config, or a one-line
        :class:`~workbench.errors.WorkbenchError` naming the flag."""
        from workbench.experiments import limits

        flags = {f: opt.flags[0] for opt in (*self.options, *self.extras) for f in opt.fields}
        limits.check_values(cfg, flags)  # first: the experiment's own checks may compute with them
        cfg.validate()
        limits.check_memory(cfg)
        return cfg

    def select(self, selection: Iterable[Any] | str | None = None) -> list[Estimator]:
        """The estimators to run: names, ``+name`` (the defaults and), specs or functions."""
        from workbench.experiments import plugins

        chosen = plugins.resolve(self, selection)
        names = [e.name for e in chosen]
        for need in reversed(self.required):
            if need not in names:
                chosen.insert(0, self.estimators[need])
        return chosen

    def estimate(self, data: Any, cfg: Any, estimators: Iterable[Any] | str | None = None,
                 record: bool = False) -> tuple[dict[str, Any], dict[str, str]]:
        """The selected estimators on a dataset you hand in (run k's, or one of your own), each
        checked and timed: the estimates by name and the failures."""
        return estimate_all(self.select(estimators), data, cfg, RunContext(record=record), self.check)

    # --- the flow, by the package's role modules
    def dataset(self, cfg: Any, run: int) -> Any:
        """Run ``run``'s dataset, made or loaded, seeded by ``(cfg.seed, run)`` (``run.make_data``)."""
        return self.role("run").make_data(cfg, run)

    def run_count(self, cfg: Any) -> int:
        """How many runs a config makes: ``cfg.runs``, unless the package's ``run`` module says
        otherwise (``run.run_count(cfg)``: sea's ``--mmsi all`` makes ``runs`` runs of each ship,
        run k's dataset being the package's to map)."""
        count = getattr(self.role("run"), "run_count", None)
        return int(count(cfg)) if count is not None else int(cfg.runs)

    def grid_values(self, name: str, values: tuple, scenario: str | None, fixed: Mapping[str, Any]
                    ) -> tuple[tuple, list[str]]:
        """A sweep's values of one setting as the experiment expands them (sea's ``mmsi=all``:
        every usable ship), and lines to say about it (what was left out and why); the
        package's ``run.grid_values`` if it has one, else the values as given."""
        expand = getattr(self.role("run"), "grid_values", None)
        return expand(name, values, scenario, fixed) if expand is not None else (values, [])

    def run_once(self, cfg: Any, run: int, estimators: list[Estimator], record: bool = False,
                 threads: int = 1) -> Any:
        """Run ``run``'s dataset and every estimator on it (``run.run_once``)."""
        return self.role("run").run_once(cfg, run, estimators, record, threads)

    def evaluate(self, result: Any, cfg: Any, run: int) -> Any:
        """A run's errors and summary (``evaluate.summarise``), small enough to send back."""
        return self.role("evaluate").summarise(result, cfg, run)

    def run_metrics(self, summary: Any, cfg: Any) -> dict[str, dict[str, float]]:
        """One run's figures per estimator, estimator -> metric -> value (a sweep's rows;
        ``evaluate.run_metrics``, units in ``evaluate.RUN_METRICS``)."""
        return self.role("evaluate").run_metrics(summary, cfg)

    @property
    def metric_units(self) -> dict[str, str]:
        return dict(self.role("evaluate").RUN_METRICS)

    def statistics(self, cfg: Any, summaries: list[Any], label: str = "") -> dict:
        """The metrics over runs (``evaluate.statistics``)."""
        return self.role("evaluate").statistics(cfg, summaries, label)

    def table(self, stats: dict) -> str:
        """The results table, markdown (``report.table``)."""
        return self.role("report").table(stats)

    def blueprint(self, first: Any, summaries: list[Any]) -> Any:
        """The recording's default layout for run 0, fitted to what it will show: run 0 and its
        evaluation ``summaries[0]``, the curves over all runs (``record.layout``)."""
        return self.role("record").layout(first, summaries)

    def record(self, rec: Any, first: Any, summaries: list[Any], table: str) -> None:
        """Draw run 0 and the curves over runs: :meth:`record_run` then :meth:`record_runs`."""
        self.record_run(rec, first, summaries[0])
        self.record_runs(rec, first, summaries, table)

    def record_run(self, rec: Any, first: Any, summary: Any) -> None:
        """Draw run 0 from its result and evaluation, all that needs no other run (``record.record_run``)."""
        self.role("record").record_run(rec, first, summary)

    def record_runs(self, rec: Any, first: Any, summaries: list[Any], table: str) -> None:
        """Draw what the Monte Carlo runs add and the results table (``record.record_runs``)."""
        self.role("record").record_runs(rec, first, summaries, table)

    def check(self, estimate: Any, data: Any, cfg: Any, estimator: Estimator) -> Any:
        """The estimate, checked against the public type (and completed where it may leave
        derived fields out); :class:`EstimateError` otherwise (``estimate.check``)."""
        return self.role("estimate").check(estimate, data, cfg, estimator)

    def label(self, first: Any) -> str:
        return first.data.label

    # --- optional hooks for an experiment's extra options (exports)
    def check_extras(self, cfg: Any, extras: dict, force: bool) -> None:
        """Check the extra outputs before any work."""

    def export(self, first: Any, stats: dict, extras: dict, force: bool) -> list[str]:
        """Extra exports after the run; lines to print."""
        return []


def without(summary: Any, names: set[str]) -> Any:
    """A copy of a run's summary (or result) with the named estimators left out of every
    field that is a dict keyed by estimator names."""
    if not names:
        return summary
    changes = {}
    for f in dataclasses.fields(summary):
        value = getattr(summary, f.name)
        if isinstance(value, dict) and names & set(value):
            changes[f.name] = {k: v for k, v in value.items() if k not in names}
    return dataclasses.replace(summary, **changes) if changes else summary
