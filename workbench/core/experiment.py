"""The experiment side of the contract: the CLI, the demo, the Python API and the sweeps reach an
experiment only through its :class:`Experiment`.

An experiment declares its scenarios and options (:mod:`.settings`), its estimator table
(:mod:`.estimator`: name -> how to run it, colour, description, causal?, covariances?) and its
metrics (:mod:`.metric`). A run flows one way: ``configure -> data -> estimate -> evaluate ->
record``. It stands on the estimator side (:mod:`.estimator`, :mod:`.metric`), which knows
nothing of it.

An experiment is a package; its ``experiment.py`` defines ``EXPERIMENT``, an :class:`Experiment`
subclass that declares the class attributes below (name, description, config type, scenarios,
options, data and estimate types, demo steps, named sweeps, commands) and, in ``declare()``, its
parts (:class:`~workbench.core.parts.Parts`: the data, the estimate check, the estimator table,
the metrics, the evaluation, the report, the recording and the optional hooks). The registry
(:mod:`workbench.core.registry`) lists it by one function, or an installed package by an entry
point of the group ``workbench.experiments``, and checks the declaration when first asked.
The packages keep one module per role by convention (``config.py``, ``scenario.py``,
``estimate.py``, ``estimators.py``, ``run.py``, ``metrics.py``, ``evaluate.py``, ``report.py``,
``record.py``), and ``declare()`` names what each gives.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from workbench.config.settings import COMMON, Option, Scenario, config_json
from workbench.core.estimator import Estimator, RunContext, estimate_all, resolve
from workbench.core.parts import Command, Demo, Later, Parts, Preset, check
from workbench.core.results import RunResult, RunSummary, without
from workbench.core.threads import on_one_blas_thread
from workbench.errors import WorkbenchError
from workbench.metrics import base as metric
from workbench.metrics import bootstrap, diagnosis, truthfree
from workbench.metrics import statistics as figures
from workbench.metrics import tables as markdown

__all__ = ["Command", "Demo", "Experiment", "Later", "Parts", "Preset", "RunResult", "RunSummary", "run_estimators",
           "without"]

def run_estimators(exp: Experiment, cfg: Any, run: int, estimators: list[Estimator], data: Any,
                   record: bool = False, threads: int = 1, **fields: Any) -> RunResult:
    """Every estimator on ``data`` as they are told to see it (:meth:`Experiment.assumed`; each
    checked by the experiment's ``check``), as the experiment's run result (its ``RunResult``,
    with ``fields`` beside the shared ones; its ``data`` the data as they are)."""
    ctx = RunContext(run, record, threads)
    estimates, failed = estimate_all(estimators, exp.assumed(data, cfg), cfg, ctx, exp.check)
    return exp.result_type(data, estimates, {e.name: e for e in estimators}, failed, ctx.products(), config=cfg,
                           record=record, metrics=exp.metrics(cfg), experiment=exp, **fields)


class Experiment:
    """The base every experiment fills; the one object the CLI, demo, API and sweeps use.

    Subclasses set the class attributes (in their package's ``experiment.py``); the flow's
    methods go to its declared parts (:meth:`declare`), and the base gives what
    is the same for all: configuration, estimator selection, the run's default flow, the
    metrics and the outer statistics.
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
    commands: tuple[Command, ...] = ()  # its own commands (`workbench measure`)
    headline: tuple[str, ...] = ()     # the metrics a sweep's report leads with
    paper_notes: Mapping[str, str] = {}  # metric -> the paper's figure, shown beside a sweep's table
    compared: tuple[str, ...] = ()     # time plots (view origins) whose curves `workbench compare` differences
    data_type: type = object           # the public dataset an estimator reads
    estimate_type: type = object       # the public estimate an estimator returns

    def declare(self) -> Parts:
        """The experiment's parts (:func:`workbench.core.parts.declare`); each experiment's own
        imports its modules here, so that listing the experiments stays quick."""
        raise WorkbenchError(f"experiment {self.name!r} declares no parts (its declare())")

    @functools.cached_property
    def parts(self) -> Parts:
        """The declared parts, made once."""
        return check(self.name, self.declare())

    def part(self, name: str) -> Any:
        """A part of the evaluation or the recording: the declared one, else the framework's
        (:mod:`workbench.core.defaults`, imported here: it draws with Rerun, which listing the
        experiments need not load)."""
        own = getattr(self.parts, name)
        if isinstance(own, Later):
            return own.load()
        if own is not None:
            return own
        from workbench.core import defaults

        return getattr(defaults, name)

    def check_declaration(self, parts: bool = True) -> Experiment:
        """The declaration checked: a name, a config type with a scenario, scenarios, commands,
        and with ``parts`` its parts (:func:`.parts.check`); one clear error naming what is wrong.
        The registry checks the class's declarations when the experiment is first asked for and
        leaves the parts to their first use (the same check, on :attr:`parts`): declaring them
        imports the experiment's modules, which listing the experiments (the command line's
        start) need not pay for."""
        if not self.name:
            raise WorkbenchError(f"{type(self).__name__} has no name")
        if not dataclasses.is_dataclass(self.config_type):
            raise WorkbenchError(f"experiment {self.name!r}: config_type is not a dataclass")
        if not self.scenarios:
            raise WorkbenchError(f"experiment {self.name!r} declares no scenarios")
        for d in self.demo:
            if d.scenario not in self.scenarios:
                raise WorkbenchError(f"experiment {self.name!r}: demo step {d.name!r} names no scenario "
                                     f"{d.scenario!r}")
        for c in self.commands:
            if not callable(c.cli) or (c.api is not None and not callable(c.api)):
                raise WorkbenchError(f"experiment {self.name!r}: command {c.name!r} is not given as functions")
        if parts:
            _ = self.parts
        return self

    @property
    def settable(self) -> tuple[Option, ...]:
        """Every option that sets a config field: the experiment's own, then those every
        experiment has (:data:`~.settings.COMMON`: ``--estimator-timeout``)."""
        return (*self.options, *COMMON)

    @property
    def estimators(self) -> dict[str, Estimator]:
        """The built-in estimator table, name -> :class:`Estimator`, in the order they run."""
        return self.parts.estimators

    @property
    def default_estimators(self) -> tuple[str, ...]:
        return tuple(self.estimators)

    # --- configure
    def configure(self, scenario: str | None = None, config: Any = None, **overrides: Any) -> Any:
        """The config of ``scenario`` with ``overrides`` on top; ``None`` means "not given" (the
        scenario's default).

        Args:
            scenario: a scenario's name; ``None``: the config file's, else the first.
            config: a config file's path (TOML or JSON, :mod:`workbench.config.files`) or a mapping
                of settings, between the scenario's defaults and the overrides.
            **overrides: config fields.

        Returns:
            The config dataclass (not yet validated: :meth:`validate`).

        Raises:
            WorkbenchError: an unknown setting, or an empty scenario (a typo, not a choice).
        """
        from workbench.config import files as configfile

        names = {f.name for f in dataclasses.fields(self.config_type)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise WorkbenchError(f"{self.name} has no setting {', '.join(unknown)}; "
                                 f"see `workbench {self.name} --help`")
        given = configfile.loads(self, config)
        from_file = given.pop("scenario", None)
        given.update({k: v for k, v in overrides.items() if v is not None})
        if scenario is None:
            scenario = from_file if from_file is not None else next(iter(self.scenarios))
        return self.config_type(scenario=scenario, **given)

    def validate(self, cfg: Any) -> Any:
        """``cfg.validate()`` (the experiment's own ranges), then the checks every experiment
        shares (:mod:`workbench.config.checks`), then its metrics resolve; the config, or a
        one-line :class:`~workbench.errors.WorkbenchError` naming the flag."""
        from workbench.config import checks as limits

        flags = {f: opt.flags[0] for opt in (*self.settable, *self.extras) for f in opt.fields}
        limits.check_values(cfg, flags)  # first: the experiment's own checks may compute with them
        cfg.validate()
        limits.check_memory(cfg)
        self.metrics(cfg)  # they resolve (and a --bootstrap the experiment cannot make is said)
        return cfg

    def select(self, selection: Iterable[Any] | str | None = None) -> list[Estimator]:
        """The estimators to run, the ones evaluation needs (``required``) put first.

        Args:
            selection: names, ``+name`` (the defaults and), ``module:function`` /
                ``file.py:function`` specs, or functions; ``None``: the defaults.

        Returns:
            Their :class:`~workbench.core.estimator.Estimator` rows, in order.

        Raises:
            WorkbenchError: anything unknown, or a name selected twice.
        """
        chosen = resolve(self, selection)
        names = [e.name for e in chosen]
        for need in reversed(self.required):
            if need not in names:
                chosen.insert(0, self.estimators[need])
        return chosen

    def estimate(self, data: Any, cfg: Any, estimators: Iterable[Any] | str | None = None,
                 record: bool = False) -> tuple[dict[str, Any], dict[str, str]]:
        """The selected estimators on a dataset you hand in (run k's, or one of your own), each
        checked and timed.

        Args:
            data: the experiment's public dataset.
            cfg: its config.
            estimators: the selection, as for :meth:`select`.
            record: compute what only the recording draws.

        Returns:
            The estimates by estimator name, and the failures by name (one line each).
        """
        return estimate_all(self.select(estimators), self.assumed(data, cfg), cfg, RunContext(record=record),
                            self.check)

    def assumed(self, data: Any, cfg: Any) -> Any:
        """The dataset as the estimators see it: the data's own noise model, or where the config
        sets what the estimators assume (``assume_*``, its package's ``run.assumed``) that instead.
        What made the data, the truth, the bounds and the evaluation stay the data's: a
        model-mismatch study varies only what the estimators are told."""
        fn = self.parts.assumed
        return data if fn is None else fn(data, cfg)

    # --- data and estimates
    @property
    def result_type(self) -> type:
        return self.parts.result_type

    def dataset(self, cfg: Any, run: int) -> Any:
        """Run ``run``'s dataset, made or loaded, seeded by ``(cfg.seed, run)`` (``run.make_data``)."""
        return self.parts.make_data(cfg, run)

    def run_count(self, cfg: Any) -> int:
        """How many runs a config makes: ``cfg.runs``, unless the package's ``run`` module says
        otherwise (``run.run_count(cfg)``: sea's ``--mmsi all`` makes ``runs`` runs of each ship)."""
        count = self.parts.run_count
        return int(count(cfg)) if count is not None else int(cfg.runs)

    def grid_values(self, name: str, values: tuple, scenario: str | None, fixed: Mapping[str, Any]
                    ) -> tuple[tuple, list[str]]:
        """A sweep's values of one setting as the experiment expands them (sea's ``mmsi=all``:
        every usable ship), and lines to say about it; the package's ``run.grid_values`` if it has one."""
        expand = self.parts.grid_values
        return expand(name, values, scenario, fixed) if expand is not None else (values, [])

    @on_one_blas_thread
    def run_once(self, cfg: Any, run: int, estimators: list[Estimator], record: bool = False,
                 threads: int = 1) -> RunResult:
        """Run ``run``'s dataset and every estimator on it: the package's ``run.run_once`` where it
        has one, else :func:`run_estimators` on :meth:`dataset`."""
        own = self.parts.run_once
        if own is not None:
            return own(self, cfg, run, estimators, record, threads)
        return run_estimators(self, cfg, run, estimators, self.dataset(cfg, run), record, threads)

    def check(self, estimate: Any, data: Any, cfg: Any, estimator: Estimator) -> Any:
        """The estimate, checked against the public type (and completed where it may leave
        derived fields out); :class:`EstimateError` otherwise (``estimate.check``)."""
        return self.parts.check(estimate, data, cfg, estimator)

    # --- evaluate: the metrics, and the experiment's own figures
    def metrics(self, cfg: Any = None) -> list[metric.Metric]:
        """The metrics of a run of ``cfg``: the package's ``metrics.METRICS``, the truth-free ones
        every experiment has (:mod:`.truthfree`), every installed metric plugin that applies, and
        the config's ``add_metrics`` (specs)."""
        extra = tuple(getattr(cfg, "add_metrics", ()) or ()) if cfg is not None else ()
        return [*_metrics(self, extra), *bootstrap.rows(self, cfg)]  # the bootstrap's NEES, where asked for

    @property
    def renamed(self) -> dict[str, str]:
        """Keys of the metrics JSON a release renamed, old -> new (kept readable for one release)."""
        return dict(self.parts.renamed)

    def settle(self, cfg: Any) -> float | None:
        """The time from which the metrics' figures count (``cfg.settle``), ``None`` where the
        experiment has no settling time."""
        value = getattr(cfg, "settle", None)
        return None if value is None else float(value)

    @on_one_blas_thread
    def evaluate(self, result: RunResult, cfg: Any, run: int) -> RunSummary:
        """A run's summary, small enough to send back: the package's ``evaluate.summarise`` and
        every metric's samples for every estimate (:func:`.metric.evaluate`)."""
        summary = self.part("summarise")(result, cfg, run)
        ctx = metric.MetricContext(cfg, run, estimates=result.estimates, estimators=result.estimators,
                                   products=result.products, cache=result.cache, result=result)
        metrics = self.metrics(cfg)
        summary.metrics, summary.metric_failures = metric.evaluate(metrics, result.data, result.estimates, ctx)
        summary.evidence = diagnosis.collect(metrics, result.estimates, summary.metrics)
        bootstrap.carry(result, summary)  # the bootstrap's iterated noise factors of the run's smoother
        return summary

    def run_metrics(self, summary: RunSummary, cfg: Any) -> dict[str, dict[str, float]]:
        """One run's figures per estimator, estimator -> metric -> value (a sweep's rows)."""
        return figures.run_rows(self.metrics(cfg), summary.metrics, self.settle(cfg))

    def metric_units(self, cfg: Any = None) -> dict[str, str]:
        return {m.name: m.unit for m in self.metrics(cfg)}

    @on_one_blas_thread  # (the diagnosis' small fits: with a BLAS thread per core, 1.9 of a MRCLAM robot's 11.5 s)
    def statistics(self, cfg: Any, summaries: list[RunSummary], label: str = "") -> dict:
        """The metrics JSON: the outer keys every experiment shares (``experiment``, ``scenario``,
        ``seed``, ``runs``, ``label``, ``config``), every metric's figures over the runs per
        estimator and its truth-free diagnosis, what the package's ``evaluate.statistics`` adds, and
        the renamed keys."""
        if not summaries:
            raise WorkbenchError("no runs to summarise")
        stats: dict = {"experiment": self.name, "scenario": cfg.scenario, "seed": cfg.seed, "runs": len(summaries),
                       "label": label, "config": config_json(cfg), "estimators": {}}
        metrics = self.metrics(cfg)
        found = figures.statistics(metrics, [s.metrics for s in summaries], self.settle(cfg))
        figures.merge(stats, metrics, found, len(summaries))
        failed: dict[str, str] = {}
        for s in summaries:
            for k, why in s.metric_failures.items():
                failed.setdefault(k, f"{why} (run {s.run})")
        if failed:
            stats["metric_failures"] = failed
        diagnosis.attach(stats, [s.evidence for s in summaries], self.parts.noise_groups)
        self.part("statistics")(self, cfg, summaries, stats)
        return figures.add_renamed(stats, self.renamed)

    def table(self, stats: dict) -> str:
        """The results table, markdown (``report.table``; without a ``report`` module the metrics'
        table, ``metrics.TABLE`` its columns, and the bounds', ``metrics.BOUNDS``), of metrics
        written by this version or the one before (their renamed keys read as the new ones)."""
        stats = figures.upgrade(_copy(stats), self.renamed)
        own = self.parts.report
        if own is not None:
            return own(stats)
        from types import SimpleNamespace

        cfg = SimpleNamespace(add_metrics=tuple(stats.get("config", {}).get("add_metrics", ()) or ()))
        return markdown.default_table(stats, self.metrics(cfg), tuple(self.parts.table_columns),
                                      tuple(self.parts.bounds))

    # --- record
    def blueprint(self, first: Any, summaries: list[Any], stats: Mapping | None = None) -> Any:
        """The recording's default layout for run 0, fitted to what it will show: run 0 and its
        evaluation ``summaries[0]``, the curves over all runs (``record.layout``); ``stats``, the
        metrics once every run is in, to a ``layout`` that takes them (its views' titles then
        name the estimators that fail their consistency tests)."""
        import inspect

        layout = self.part("layout")
        if stats is not None and "stats" in inspect.signature(layout).parameters:
            return layout(first, summaries, stats=stats)
        return layout(first, summaries)

    def record(self, rec: Any, first: Any, summaries: list[Any], table: str) -> None:
        """Draw run 0 and the curves over runs: :meth:`record_run` then :meth:`record_runs`."""
        self.record_run(rec, first, summaries[0])
        self.record_runs(rec, first, summaries, table)

    def record_run(self, rec: Any, first: Any, summary: Any) -> None:
        """Draw run 0 from its result and evaluation, all that needs no other run (``record.record_run``)."""
        self.part("record_run")(rec, first, summary)

    def record_runs(self, rec: Any, first: Any, summaries: list[Any], table: str) -> None:
        """Draw what the Monte Carlo runs add and the results table (``record.record_runs``)."""
        self.part("record_runs")(rec, first, summaries, table)

    def label(self, first: Any) -> str:
        return first.data.label

    # --- optional hooks for an experiment's extra options (exports)
    @property
    def writes_logs(self) -> bool:
        """It can write a dataset in its open log format (``run.write_log``: ``--export-data``)."""
        return self.parts.write_log is not None

    def check_extras(self, cfg: Any, extras: dict, force: bool) -> None:
        """Check the extra outputs before any work (a subclass calls this one too)."""
        folder = extras.get("export_data")
        if folder is not None:
            if not self.writes_logs:
                raise WorkbenchError(f"{self.name} has no log format to export to (--export-data)")
            if not str(folder).strip() or Path(folder).is_file():
                raise WorkbenchError(f"--export-data {folder!r}: name a folder")

    def export(self, first: Any, stats: dict, extras: dict, force: bool) -> list[str]:
        """Extra exports after the run (a subclass calls this one too); lines to print:
        ``export_data``, run 0's dataset in the experiment's open log format."""
        folder = extras.get("export_data")
        if folder is None:
            return []
        written = self.parts.write_log(first.data, Path(folder), force)
        stats["exported_data"] = [str(p) for p in written]
        return [f"log:       {folder}/ (read it back: --scenario log --data {folder})"]


@functools.lru_cache(maxsize=64)
def _metrics(exp: Experiment, extra: tuple) -> tuple[metric.Metric, ...]:
    own = exp.parts.metrics
    common = tuple(m for m in truthfree.METRICS if m.name not in {x.name for x in own})
    return tuple(metric.select((*own, *common), exp.name, extra))


def _copy(stats: dict) -> dict:
    import copy

    return copy.deepcopy(stats)
