"""The Python API, and the one code path every experiment runs through (the CLI is a thin
layer over :func:`run`).

```python
import workbench
res = workbench.run("sea", scenario="paper", runs=10, estimators=["geometric", "gtsam", my_filter])
res.metrics["estimators"]["my_filter"]["position_rmse"], res.estimates["my_filter"].position
```

``run`` configures (the scenario's defaults under the overrides), checks every output before
any work, runs run 0 (kept whole: ``res.first``, ``res.data``, ``res.estimates``) and the other
Monte Carlo runs over processes (their summaries: ``res.summaries``), reduces them to the
metrics and the table, writes the recording and the metrics file if asked, and returns. An
estimator that fails (raises, or returns an estimate that breaks its type) is left out of
every run, named in ``res.failures`` and the metrics' ``failed``; the others' results stand.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from workbench import loading
from workbench.config import checks as limits
from workbench.core import montecarlo
from workbench.core.experiment import Experiment, without
from workbench.core.registry import get
from workbench.errors import WorkbenchError
from workbench.metrics import base as metric


@dataclass
class Result:
    """What :func:`run` returns."""

    experiment: str
    config: Any
    metrics: dict
    table: str
    first: Any = None                    # run 0's result: its dataset and every estimate
    summaries: list = field(default_factory=list)
    recording: Path | None = None
    metrics_path: Path | None = None
    failures: dict[str, str] = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)  # what the exports wrote
    live: Any = None                     # the live stream (--spawn / --serve / --connect), kept open

    @property
    def data(self) -> Any:
        return self.first.data

    @property
    def estimates(self) -> dict:
        return self.first.estimates


def configure(experiment: str | Experiment, scenario: str | None = None, config: Any = None,
              **overrides: Any) -> Any:
    """The config ``run`` would use (validated), for a look before running.

    Args:
        experiment: its name (``"omni"``, ``"sea"``, ``"terrain"`` or an installed one) or the object.
        scenario: a scenario's name; ``None``: the config file's, else the first.
        config: a ready config, or a config file's path, or a mapping of settings (as for :func:`run`).
        **overrides: config fields, on top of the scenario's defaults and the config.

    Returns:
        The experiment's config dataclass, checked (a one-line ``WorkbenchError`` otherwise).
    """
    exp = get(experiment) if isinstance(experiment, str) else experiment
    if config is not None and dataclasses.is_dataclass(config):
        return exp.validate(dataclasses.replace(config, **{k: v for k, v in overrides.items() if v is not None}))
    return exp.validate(exp.configure(scenario, config, **overrides))


def run(experiment: str | Experiment, scenario: str | None = None, *, config: Any = None,
        estimators: Iterable[Any] | str | None = None,
        out: str | Path | None = None, metrics: str | Path | None = None, force: bool = False,
        jobs: int | None = None, spawn: bool = False, serve: bool = False, connect: str | None = None,
        progress: Callable[[int, int], None] | None = None, extras: dict | None = None,
        export_data: str | Path | None = None, **overrides: Any) -> Result:
    """Run an experiment: ``runs`` Monte Carlo runs (``seed``, ``runs`` and every other config
    field as keyword overrides), every selected estimator on each run's data.

    ``config``: a ready config instead of ``scenario`` (the overrides then replace its fields), or
    a config file's path (TOML or JSON: ``--config``) or a mapping of settings, which go between the
    scenario's defaults and the overrides (:mod:`workbench.config.files`).
    ``estimators``: names, ``+name`` (the defaults and), ``module:function`` / ``file.py:function``
    specs, or functions ``(data, cfg) -> Estimate``. ``out``: write run 0's recording there
    (``.rrd``); ``metrics``: the metrics JSON; neither overwrites without ``force``.
    ``spawn`` / ``serve`` / ``connect``: stream live to a spawned viewer, a gRPC server of this
    process, or a running viewer at a ``rerun+http://...`` URL: run 0 as soon as it is computed,
    the curves over runs and the table when the Monte Carlo runs are done (the saved recording is
    the same either way: it is written from the same results, whatever is streamed). A viewer that
    is not there is a one-line error before any work (:func:`stream.live`); one lost during the run
    is a :class:`stream.LiveWarning` once the outputs are written (:func:`stream.finish_live`).
    ``extras``: the experiment's extra options (e.g. omni's ``export_tum``, terrain's ``model``);
    ``export_data``: a folder for run 0's dataset in the experiment's open log format. ``progress(done,
    total)`` is called as runs finish.

    Args:
        experiment: its name or the object.
        scenario: a scenario's name (``None``: the config's, else the first).
        config: a ready config, a config file's path or a mapping of settings.
        estimators: the selection (names, ``+name``, specs, functions); ``None``: the config's or the defaults.
        out: the recording's path (``.rrd``), or ``None`` for none.
        metrics: the metrics JSON's path, or ``None``.
        force: overwrite ``out`` and ``metrics`` where they exist.
        jobs: worker processes for the Monte Carlo runs (``None``: the cores).
        spawn: stream live to a spawned viewer.
        serve: serve the stream over gRPC from this process.
        connect: stream to a running viewer at this ``rerun+http://...`` URL.
        progress: called with ``(done, total)`` as runs finish.
        extras: the experiment's extra options.
        export_data: a folder for run 0's dataset in the open log format.
        **overrides: config fields (``runs``, ``seed``, ``sigma_bearing_deg``, ...).

    Returns:
        A :class:`Result`: the config, run 0's data and estimates, every run's summary, the
        metrics (as in the JSON), the results table, and the paths written.

    Raises:
        WorkbenchError: bad input (one line, before any work).
    """
    from workbench.recording import stream

    exp = get(experiment) if isinstance(experiment, str) else experiment
    extras = dict(extras or {})
    if export_data is not None:
        extras["export_data"] = export_data
    if config is not None and dataclasses.is_dataclass(config):
        cfg = dataclasses.replace(config, **{k: v for k, v in overrides.items() if v is not None})
    else:
        cfg = exp.configure(scenario, config, **overrides)
    chosen = exp.select(estimators if estimators is not None else (cfg.estimators or None))
    cfg.estimators = tuple(e.spec for e in chosen)
    added = cfg.add_metrics
    added = loading.split_list(added) if isinstance(added, str) else tuple(added or ())  # one spec, or several
    cfg.add_metrics = tuple(metric.spec(m, exp.name) for m in added)
    exp.validate(cfg)
    limits.check_jobs(jobs)
    out_path = stream.check_output(Path(out), force) if out is not None else None
    metrics_path = stream.check_plain_output(Path(metrics), force, "metrics file") if metrics is not None else None
    if out_path is not None and metrics_path is not None and out_path.resolve() == metrics_path.resolve():
        raise WorkbenchError(f"--metrics and --out name the same file ({out_path}): one would replace the other")
    extras["recording"] = out_path  # exports that sit beside the recording (terrain's model folder)
    exp.check_extras(cfg, extras, force)
    tuned = None
    if cfg.tune_noise:  # the noise the data identify, told to every estimator; the stored config then runs as is
        from workbench.core import selftune

        cfg, tuned = selftune.tune_noise(exp, cfg)
        cfg = exp.validate(dataclasses.replace(cfg, tune_noise=False))
    report = progress or (lambda done, total: None)
    t0 = time.perf_counter()
    done = [0]

    total = exp.run_count(cfg)

    def tick(n: int) -> None:
        done[0] += n
        report(done[0], total)

    live = stream.live(exp.name, cfg.to_json(), cfg.seed, spawn, serve, connect)
    try:
        report(0, total)
        first = exp.run_once(cfg, 0, chosen, record=True, threads=min(2, jobs or 2))
        zero = exp.evaluate(first, cfg, 0)
        if live is not None:  # run 0 now, while the other runs compute
            live.send_blueprint(exp.blueprint(without(first, set(first.failed)), [zero]), make_active=True)
            exp.record_run(live, without(first, set(first.failed)), zero)
        worker = functools.partial(summarise_run, exp.name, cfg, chosen)
        summaries = montecarlo.run_all(worker, total, zero, jobs, tick)
        failures: dict[str, str] = {}
        for s in summaries:
            for name, why in s.failed.items():
                failures.setdefault(name, f"{why} (run {s.run})")
        for name, why in first.failed.items():
            failures.setdefault(name, f"{why} (run 0)")
        gone = set(failures)
        summaries = [without(s, gone) for s in summaries]
        first = without(first, gone)
        stats = exp.statistics(cfg, summaries, exp.label(first))
        stats["estimator_table"] = {e.name: e.describe() for e in chosen if e.name not in gone}
        if failures:
            stats["failed"] = failures
        if tuned is not None:
            stats["tuned_noise"] = tuned
        stats["wall_seconds"] = time.perf_counter() - t0
        table = exp.table(stats)
        if live is not None:  # sent in the background: a viewer gone by now holds nothing up
            exp.record_runs(live, first, summaries, table)
            live.send_blueprint(exp.blueprint(first, summaries, stats), make_active=True, make_default=True)
        if out_path is not None:
            with stream.recording(out_path, exp.name, cfg.to_json(), cfg.seed, exp.blueprint(first, summaries, stats),
                                  metrics=stats, force=force) as rec:
                exp.record(rec, first, summaries, table)
            stats["recording"] = str(out_path)
        lines = exp.export(first, stats, extras, force)
        if tuned is not None:
            from workbench.core import tune_report

            lines = tune_report.lines(tuned) + lines
        if metrics_path is not None:
            stream.write_text_atomic(metrics_path, strict_json(stats), force)
        if live is not None:  # the outputs are written: only now wait (at most LIVE_FLUSH) for the viewer
            why = stream.finish_live(live)
            if why is not None:
                warnings.warn(f"the live viewer: {why}; the recording is written all the same",
                              stream.LiveWarning, stacklevel=2)
        for name, why in failures.items():
            warnings.warn(f"estimator {name!r} failed: {why}", RuntimeWarning, stacklevel=2)
        return Result(exp.name, cfg, stats, table, first, summaries, out_path, metrics_path, failures, lines, live)
    except BaseException:
        if live is not None:  # an error or Ctrl-C: a viewer that does not answer must not hold the exit
            stream.finish_live(live, timeout=1.0)
        raise


def command(name: str) -> Callable:
    """A command an experiment declares (terrain's ``measure``), as its Python function: found in
    the registry, the way the command line finds it."""
    from workbench.core import registry as experiments

    for exp in experiments.all_experiments():
        for cmd in exp.commands:
            if cmd.name == name and cmd.api is not None:
                return cmd.api()
    raise AttributeError(f"module 'workbench.api' has no attribute {name!r}")


def __getattr__(name: str) -> Callable:
    """``api.measure`` and any other command an experiment declares (:func:`command`)."""
    if name.startswith("_"):
        raise AttributeError(name)
    return command(name)


def summarise_run(experiment: str, cfg: Any, estimators: list, run: int) -> Any:
    """One Monte Carlo run, in whatever process: its dataset, every estimator, its summary."""
    exp = get(experiment)
    return exp.evaluate(exp.run_once(cfg, run, estimators), cfg, run)


def strict_json(stats: dict) -> str:
    """The metrics as strict JSON: a non-finite number (NaN, infinity: no JSON has them) is
    written as ``null`` and its place named under ``"non_finite"`` with its value."""
    where: dict[str, str] = {}

    def clean(x: Any, path: str) -> Any:
        if isinstance(x, dict):
            return {k: clean(v, f"{path}.{k}" if path else str(k)) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v, f"{path}[{i}]") for i, v in enumerate(x)]
        if isinstance(x, float) and not math.isfinite(x):
            where[path] = str(x)
            return None
        if hasattr(x, "item") and getattr(x, "ndim", 1) == 0:  # a numpy scalar
            return clean(x.item(), path)
        return x

    out = clean(stats, "")
    if where:
        out["non_finite"] = {"why": "not a number or infinite (no estimate, or a division by zero): written as null",
                             "values": where}
    return json.dumps(out, indent=2, allow_nan=False, default=str)
