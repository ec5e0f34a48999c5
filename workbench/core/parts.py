"""What an experiment declares: its parts (:class:`Parts`), one attribute each, and its demo
steps, named sweeps and commands.

An experiment's ``experiment.py`` gives its :class:`~workbench.core.experiment.Experiment` a
``declare()`` that imports its own modules (statically: the import test sees every edge) and
returns its :class:`Parts`, checked on their first use (:func:`check`): a part missing, misnamed
or of the wrong kind is one clear error naming it. Nothing is looked up by a module's name.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from workbench.core.estimator import Estimator
from workbench.core.results import RunResult
from workbench.errors import WorkbenchError
from workbench.metrics.base import Metric


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
    """A named sweep: ``grid`` (config field -> values) on ``scenario`` with ``overrides``;
    ``report``, where it writes its own report too, a function ``(table, folder, definition) ->
    paths``."""

    name: str
    description: str
    grid: Mapping[str, tuple]
    scenario: str | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    estimators: str | None = None
    report: Callable | None = None


@dataclass(frozen=True)
class Command:
    """A command an experiment adds to the command line and the Python API (terrain's
    ``measure``): ``cli`` gives the typer command function, ``api`` the function
    ``workbench.<name>``; each a function of no arguments that imports it when first used (the
    command line lists every experiment's commands without importing them)."""

    name: str
    cli: Callable[[], Callable]
    api: Callable[[], Callable] | None = None


@dataclass(frozen=True)
class Later:
    """A part imported on its first use: ``load`` gives the function (a module that loads Rerun or
    GTSAM need not be imported to list the experiments or build the command line). Calling it
    calls that function."""

    load: Callable[[], Callable]

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.load()(*args, **kwargs)


@dataclass(frozen=True, kw_only=True)
class Parts:
    """An experiment's parts, one attribute each. The first four are required; the rest are
    absent (``None``): the evaluation's and the recording's then are the framework's
    (:mod:`workbench.core.defaults`, :meth:`Experiment.part`), imported only when used. Any function
    may be given as :class:`Later`, imported on its first use.

    Data and estimates:
        make_data: ``(cfg, run) -> data``, run k's dataset, made or loaded.
        check: ``(estimate, data, cfg, estimator) -> estimate``, the estimate checked against
            the public type (:class:`~workbench.core.estimator.EstimateError` otherwise).
        estimators: the built-in estimator table, name -> :class:`~workbench.core.estimator.Estimator`.
        metrics: the metrics that apply (:class:`~workbench.metrics.base.Metric` rows).
        assumed: ``(data, cfg) -> data``, the data as the estimators are told to see it (``assume_*``).
        result_type: the run's result (a :class:`~workbench.core.results.RunResult` with more fields).
        run_once: ``(experiment, cfg, run, estimators, record, threads) -> RunResult``, where a run
            is more than its dataset and its estimators (an image stage).
        run_count: ``cfg -> int``, where a config makes another number of runs than ``cfg.runs``.
        grid_values: ``(name, values, scenario, fixed) -> (values, lines)``, a sweep's values expanded.
        write_log: ``(data, folder, force) -> paths``, the dataset in the open log format (``--export-data``).
        tunable, components: what ``--tune-noise`` tunes, and its groups (:mod:`workbench.core.selftune`).
        hold_rows: ``estimate -> context manager`` in which the tuned filter makes that estimate's
            rows again whatever noise it is told (omni's EKF: its landmarks' initialisations),
            where its rows change with the noise (:class:`workbench.core.objective._Objective`).
        resample, bootstrap_nees: the parametric bootstrap (:mod:`workbench.metrics.bootstrap`)
            and the metric it reads.

    Evaluation and the report:
        summarise: ``(result, cfg, run) -> RunSummary``, the run's own figures.
        statistics: ``(experiment, cfg, summaries, stats) -> None``, what it adds to the metrics JSON.
        report: ``stats -> markdown``, its results table; without one, the metrics' table of
            ``table_columns`` and the ``bounds``.
        renamed: keys of the metrics JSON a release renamed, old -> new.
        noise_groups: the noise groups' names in the diagnosis (:mod:`workbench.metrics.diagnosis`).

    The recording:
        layout: ``(first, summaries[, stats]) -> Blueprint``, the default layout.
        record_run: ``(rec, first, summary)``, run 0; record_runs: ``(rec, first, summaries, table)``.
    """

    make_data: Callable
    check: Callable
    estimators: Mapping[str, Estimator]
    metrics: tuple[Metric, ...]
    assumed: Callable | None = None
    result_type: type = RunResult
    run_once: Callable | None = None
    run_count: Callable | None = None
    grid_values: Callable | None = None
    write_log: Callable | None = None
    tunable: Callable | None = None
    components: Callable | None = None
    hold_rows: Callable | None = None
    resample: Callable | None = None
    bootstrap_nees: str | None = None
    summarise: Callable | None = None
    statistics: Callable | None = None
    report: Callable | None = None
    table_columns: tuple[str, ...] = ()
    bounds: tuple = ()
    renamed: Mapping[str, str] = field(default_factory=dict)
    noise_groups: Mapping[str, str] = field(default_factory=dict)
    layout: Callable | None = None
    record_run: Callable | None = None
    record_runs: Callable | None = None


NAMES = tuple(f.name for f in dataclasses.fields(Parts))
REQUIRED = tuple(f.name for f in dataclasses.fields(Parts)
                 if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING)


def declare(experiment: str, **parts: Any) -> Parts:
    """The :class:`Parts` of an experiment, checked by name.

    Args:
        experiment: the experiment's name (for the errors).
        **parts: its parts by name (:class:`Parts`' fields).

    Returns:
        The parts.

    Raises:
        WorkbenchError: a part misnamed (with the names there are) or a required one missing.
    """
    wrong = sorted(set(parts) - set(NAMES))
    if wrong:
        raise WorkbenchError(f"experiment {experiment!r} declares no part called {', '.join(wrong)}; "
                             f"its parts are {', '.join(NAMES)}")
    missing = [n for n in REQUIRED if n not in parts]
    if missing:
        raise WorkbenchError(f"experiment {experiment!r} does not declare its {', '.join(missing)} "
                             "(a required part)")
    return Parts(**parts)


def check(experiment: str, parts: Any) -> Parts:
    """``parts`` checked: a :class:`Parts`; functions where functions go; an estimator table of
    :class:`Estimator` rows; :class:`Metric` rows. One clear error naming the part otherwise."""
    if not isinstance(parts, Parts):
        raise WorkbenchError(f"experiment {experiment!r}: declare() gives {type(parts).__name__}, not Parts "
                             "(workbench.core.parts.declare)")
    for f in dataclasses.fields(Parts):
        value = getattr(parts, f.name)
        if f.type.startswith("Callable") and value is not None and not callable(value):
            raise WorkbenchError(f"experiment {experiment!r}: its part {f.name} is {type(value).__name__}, "
                                 "not a function")
    if not isinstance(parts.estimators, Mapping) or not all(isinstance(e, Estimator)
                                                            for e in parts.estimators.values()):
        raise WorkbenchError(f"experiment {experiment!r}: its part estimators is not a table of Estimator rows")
    if not all(isinstance(m, Metric) for m in parts.metrics):
        raise WorkbenchError(f"experiment {experiment!r}: its part metrics holds something not a Metric")
    if not (isinstance(parts.result_type, type) and issubclass(parts.result_type, RunResult)):
        raise WorkbenchError(f"experiment {experiment!r}: its part result_type is not a RunResult")
    return parts
