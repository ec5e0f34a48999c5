"""The experiment commands: one per registered experiment, built from its contract (its
scenarios, options, extras and estimator table) by one code path, and what every one of them
does (:func:`execute`: the API's run, the table and the outputs printed). Nothing here knows an
experiment's settings."""

from __future__ import annotations

import inspect
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

import typer

from workbench.loading import split_list
from workbench.paths import PROJECT_ROOT

RECORDINGS = PROJECT_ROOT / "recordings"
FAILED = 3  # the run finished, but an estimator failed (its results are left out)
QUIET_SDK = "warn,re_grpc_client=off,re_sdk::recording_stream=off,re_sdk::grpc_server=off"
"""``RUST_LOG`` for a command that streams live: the SDK's own log lines about a viewer that went
away or never answered (a dozen, timestamped, on stderr) silenced; the run says it in one line
(:class:`~workbench.recording.stream.LiveWarning`). The SDK reads it once, when ``rerun`` is first
imported; a ``RUST_LOG`` the user set is kept."""


def _progress():
    """A progress bar (rich, which typer brings) that shows itself only on a terminal."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   transient=True, disable=not sys.stderr.isatty())
    return bar, bar.add_task("runs", total=None)


def execute(exp, scenario: str | None, out: Path | None, force: bool, metrics: Path | None, spawn: bool = False,
            serve: bool = False, jobs: int | None = None, estimators: str | None = None, quiet: bool = False,
            extras: dict | None = None, connect: str | None = None, config: Path | None = None, **overrides):
    """What every experiment command does, through the API; prints the table and the outputs.
    Exits with :data:`FAILED` (after writing everything) if an estimator or a metric failed."""
    import os

    if spawn or serve or connect is not None:
        os.environ.setdefault("RUST_LOG", QUIET_SDK)  # before the first import of rerun (below)
    from workbench import api

    bar, task = _progress()
    from workbench._moved import MovedWarning
    from workbench.errors import DataWarning
    from workbench.recording.stream import VIEWER_PORT, LiveWarning

    with bar, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("ignore", RuntimeWarning)  # the failures are printed below
        warnings.simplefilter("always", LiveWarning)
        warnings.simplefilter("always", DataWarning)
        warnings.simplefilter("always", MovedWarning)  # a plugin on an old module path: where it went
        res = api.run(exp, scenario, estimators=estimators, out=out or RECORDINGS / f"{exp.name}.rrd",
                      metrics=metrics, force=force, jobs=jobs, spawn=spawn, serve=serve, connect=connect,
                      config=config,
                      extras=extras, progress=lambda done, total: bar.update(task, completed=done, total=total),
                      **overrides)
    told = (LiveWarning, DataWarning, MovedWarning)
    said = dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, told))
    for line in said:  # a real log is read once per run: each repair said once
        typer.echo(f"warning: {line}", err=True)
    if not quiet:
        wall = res.metrics.get("wall_seconds")
        lines = ([f"recording: {res.recording}"] if res.recording else []) + (
            [f"metrics:   {res.metrics_path}"] if res.metrics_path else []) + res.lines + (
            [f"{len(res.summaries) or res.config.runs} run(s) in {wall:.1f} s"] if wall is not None else [])
        typer.echo(res.table + "\n\n" + "\n".join(lines))
    for name, why in res.failures.items():
        typer.echo(f"error: estimator {name!r} failed: {why}", err=True)
    broken = res.metrics.get("metric_failures", {})
    for where, why in dict.fromkeys(broken.items()):
        estimator, _, metric = where.rpartition("/")
        typer.echo(f"error: metric {metric!r} failed on {estimator!r}: {why}", err=True)
    if serve and res.live is not None:
        typer.echo(f"serving the stream at rerun+http://127.0.0.1:{VIEWER_PORT}/proxy "
                   f"(rerun --connect rerun+http://127.0.0.1:{VIEWER_PORT}/proxy); Ctrl-C to stop", err=True)
        _until_interrupted()
    if res.failures or broken:
        raise typer.Exit(FAILED)
    return res


def _until_interrupted() -> None:
    import time

    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        typer.echo("stopped serving", err=True)


def _option(opt, exp) -> inspect.Parameter:
    help_text = _escape(opt.described(exp.config_type, exp.scenarios))
    kind = str if opt.type is Path else opt.type  # a path as text: '' is an error, not the current folder
    return inspect.Parameter(opt.field, inspect.Parameter.KEYWORD_ONLY, annotation=kind | None,
                             default=typer.Option(None, *opt.flags, help=help_text))


def _escape(text: str) -> str:
    """Brackets as text, not rich markup (which would swallow ``[recordings/sea.rrd]``)."""
    return text.replace("[", "\\[")


def _shared(exp) -> list[inspect.Parameter]:
    """The options every experiment command has, declared once."""
    builtin = ", ".join(exp.estimators)
    rows = [("scenario", str, f"{' | '.join(exp.scenarios)} [{next(iter(exp.scenarios))}]"),
            ("config", str, "A TOML or JSON file of settings (the options' names; a recording's stored config "
                             "as `workbench info REC --config` prints it): beneath the options given here."),
            ("seed", int, "Seed of every random draw [0]."),
            ("runs", int, "Monte Carlo runs (run 0 is recorded in full) [1]."),
            ("out", Path, f"Recording path [recordings/{exp.name}.rrd]."),
            ("force", bool, "Overwrite existing outputs."),
            ("metrics", Path, "Write the metrics JSON here."),
            ("spawn", bool, "Also stream live to a spawned native viewer (run 0 as soon as it is done)."),
            ("serve", bool, "Also serve the stream over gRPC, live, until Ctrl-C."),
            ("connect", str, "Also stream live to a running viewer at this URL (rerun+http://HOST:PORT/proxy)."),
            ("jobs", int, "Processes for Monte Carlo runs [up to 2]."),
            ("estimators", str, f"Comma-separated: {builtin} (the defaults), installed plugins, your own as "
                                "module:function or file.py:function; +name adds to the defaults."),
            ("add_metrics", str, "Comma-separated metrics of your own (module:function or file.py:function), "
                                 "beside the experiment's and the installed ones.")]
    tune = inspect.Parameter("tune_noise", inspect.Parameter.KEYWORD_ONLY, annotation=bool | None,
                             default=typer.Option(None, "--tune-noise/--no-tune-noise", help=_escape(
                                 "First estimate the noise the data identify, by a filter's likelihood on the "
                                 "data (no truth used); every estimator then assumes it [off; sea ais on].")))
    if exp.writes_logs:
        rows.append(("export_data", str, "Write run 0's dataset into this folder in the open log format "
                                          "(docs/log-formats.md; read it back with --scenario log --data)."))
    return [inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY, annotation=t if t is bool else t | None,
                              default=typer.Option(False if t is bool else None, help=_escape(h))) for n, t, h in rows
            ] + [tune]


def command(exp, friendly: Callable[[Callable], Callable]) -> Callable:
    """The experiment's command: its options as typer parameters, bad input made one line by ``friendly``."""

    def run(**given):
        shared = {k: given.pop(k) for k in ("scenario", "out", "force", "metrics", "spawn", "serve", "jobs",
                                            "estimators", "connect", "config")}
        extras = {opt.field: opt.value(given.pop(opt.field)) for opt in exp.extras}
        if "export_data" in given:
            extras["export_data"] = given.pop("export_data")
        added = given.pop("add_metrics")
        overrides = {"seed": given.pop("seed"), "runs": given.pop("runs"), "tune_noise": given.pop("tune_noise"),
                     "add_metrics": split_list(added) if added is not None else None}
        for opt in exp.settable:
            value = opt.value(given.pop(opt.field))
            overrides.update({f: value for f in opt.fields if value is not None})
        execute(exp, extras=extras, **shared, **overrides)

    params = _shared(exp) + [_option(o, exp) for o in exp.settable + exp.extras]
    wrapped = friendly(run)
    wrapped.__signature__ = inspect.Signature(params)
    wrapped.__annotations__ = {p.name: p.annotation for p in params}
    wrapped.__doc__ = exp.description[0].upper() + exp.description[1:] + "."
    return wrapped


