"""The ``workbench`` launcher: a thin typer layer over :func:`workbench.api.run`.

One command per registered experiment, built from its contract (its scenarios, options and
estimator table) by one code path; plus ``list``, ``demo``, ``view``, ``info`` / ``replay``
(:mod:`workbench.recording.commands`) and ``sweep`` / ``sweep-report``
(:mod:`workbench.sweeps.commands`). Nothing here knows an experiment's settings.
"""

from __future__ import annotations

import os

# The estimators multiply small matrices: BLAS threads only add overhead, and Monte Carlo
# runs already use both cores. Set before numpy is first imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import inspect
import json
import shutil
import subprocess
import sys
import warnings
from collections.abc import Callable
from functools import wraps
from pathlib import Path

import typer

from workbench import experiments
from workbench.errors import DataNotFound, WorkbenchError
from workbench.paths import PROJECT_ROOT
from workbench.recording import commands as recording_commands
from workbench.sweeps import commands as sweep_commands

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Estimation workbench: paper estimators against GTSAM, recorded to Rerun.")
RECORDINGS = PROJECT_ROOT / "recordings"
FAILED = 3  # the run finished, but an estimator failed (its results are left out)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the process is, so every ``finally`` (temporary files, worker
    pools) runs as it does for Ctrl-C."""


def _on_sigterm(signum, frame) -> None:
    raise Terminated()


def main() -> None:
    """The ``workbench`` command: SIGTERM handled like Ctrl-C (outputs cleaned up, workers
    ended, one line, no traceback), then :func:`run_cli` on the command line."""
    import signal

    signal.signal(signal.SIGTERM, _on_sigterm)
    sys.exit(run_cli())


def run_cli(argv: list[str] | None = None) -> int:
    """The typer app on ``argv`` (default: the process's), its exit code returned; what the
    argument parser refuses (an unknown flag, a value of the wrong type) is one line on stderr
    and code 2, not the parser's boxed usage text."""
    # typer carries its own click: its exceptions are the ones raised here
    usage_error = typer.BadParameter.__mro__[1]
    click_exception = usage_error.__mro__[1]
    try:
        code = app(args=argv, standalone_mode=False)
    except usage_error as exc:
        if not exc.format_message():  # no arguments at all: the help was printed
            return exc.exit_code
        where = exc.ctx.command_path if exc.ctx is not None else "workbench"
        typer.echo(f"error: {exc.format_message()} (see `{where} --help`)", err=True)
        return 2
    except click_exception as exc:
        typer.echo(f"error: {exc.format_message()}", err=True)
        return exc.exit_code
    except (typer.Abort, KeyboardInterrupt):
        typer.echo("interrupted", err=True)
        return 130
    return code if isinstance(code, int) else 0


def friendly(fn: Callable) -> Callable:
    """Bad input becomes one line on stderr and exit code 2, never a traceback."""

    @wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except WorkbenchError as exc:
            typer.echo(f"error: {exc}", err=True)
            raise typer.Exit(2) from None
        except Terminated:
            typer.echo("terminated (SIGTERM); nothing half-written is left", err=True)
            raise typer.Exit(143) from None
        except KeyboardInterrupt:
            typer.echo("interrupted; nothing half-written is left", err=True)
            raise typer.Exit(130) from None
        except (typer.Exit, SystemExit):
            raise
        except Exception as exc:  # a bug, not bad input: one line unless debugging
            if os.environ.get("WORKBENCH_DEBUG"):
                raise
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
            typer.echo(f"internal error: {type(exc).__name__}: {first} "
                       "(set WORKBENCH_DEBUG=1 for the traceback)", err=True)
            raise typer.Exit(1) from None

    return wrapper


def _progress():
    """A progress bar (rich, which typer brings) that shows itself only on a terminal."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   transient=True, disable=not sys.stderr.isatty())
    return bar, bar.add_task("runs", total=None)


def execute(exp, scenario: str | None, out: Path | None, force: bool, metrics: Path | None, spawn: bool = False,
            serve: bool = False, jobs: int | None = None, estimators: str | None = None, quiet: bool = False,
            extras: dict | None = None, connect: str | None = None, **overrides):
    """What every experiment command does, through the API; prints the table and the outputs.
    Exits with :data:`FAILED` (after writing everything) if an estimator failed."""
    from workbench import api

    bar, task = _progress()
    from workbench.errors import DataWarning
    from workbench.recording.stream import VIEWER_PORT, LiveWarning

    with bar, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("ignore", RuntimeWarning)  # the failures are printed below
        warnings.simplefilter("always", LiveWarning)
        warnings.simplefilter("always", DataWarning)
        res = api.run(exp, scenario, estimators=estimators, out=out or RECORDINGS / f"{exp.name}.rrd",
                      metrics=metrics, force=force, jobs=jobs, spawn=spawn, serve=serve, connect=connect,
                      extras=extras, progress=lambda done, total: bar.update(task, completed=done, total=total),
                      **overrides)
    said = dict.fromkeys(str(w.message) for w in caught if issubclass(w.category, (LiveWarning, DataWarning)))
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
    if serve and res.live is not None:
        typer.echo(f"serving the stream at rerun+http://127.0.0.1:{VIEWER_PORT}/proxy "
                   f"(rerun --connect rerun+http://127.0.0.1:{VIEWER_PORT}/proxy); Ctrl-C to stop", err=True)
        _until_interrupted()
    if res.failures:
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
                                "module:function or file.py:function; +name adds to the defaults.")]
    return [inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY, annotation=t if t is bool else t | None,
                              default=typer.Option(False if t is bool else None, help=_escape(h))) for n, t, h in rows]


def _command(exp) -> Callable:
    def command(**given):
        shared = {k: given.pop(k) for k in ("scenario", "out", "force", "metrics", "spawn", "serve", "jobs",
                                            "estimators", "connect")}
        extras = {opt.field: opt.value(given.pop(opt.field)) for opt in exp.extras}
        overrides = {"seed": given.pop("seed"), "runs": given.pop("runs")}
        for opt in exp.options:
            value = opt.value(given.pop(opt.field))
            overrides.update({f: value for f in opt.fields if value is not None})
        execute(exp, extras=extras, **shared, **overrides)

    params = _shared(exp) + [_option(o, exp) for o in exp.options + exp.extras]
    wrapped = friendly(command)
    wrapped.__signature__ = inspect.Signature(params)
    wrapped.__annotations__ = {p.name: p.annotation for p in params}
    wrapped.__doc__ = exp.description[0].upper() + exp.description[1:] + "."
    return wrapped


for _exp in experiments.all_experiments():
    app.command(_exp.name)(_command(_exp))
app.command("sweep")(friendly(sweep_commands.sweep))
app.command("sweep-report")(friendly(sweep_commands.sweep_report))
app.command("info")(friendly(recording_commands.info))
app.command("replay")(friendly(recording_commands.replay))
app.command("screenshot")(friendly(recording_commands.screenshot))
app.command("compare")(friendly(recording_commands.compare))


@app.command("measure")
@friendly
def measure(model: str = typer.Argument(..., help="A halftone model folder (a terrain run's <out>.model)."),
            point: list[str] = typer.Option([], "--point", help="u,v: image II's pixel -> ground X, Y, H and the "
                                            "terrain's slope there (repeatable)."),
            line: list[str] = typer.Option([], "--line", help="u1,v1:u2,v2 -> distance, slope distance, height "
                                           "difference, slope (repeatable)."),
            polygon: list[str] = typer.Option([], "--polygon", help="u1,v1:u2,v2:u3,v3... -> area, perimeter, mean "
                                              "height (repeatable)."),
            as_json: bool = typer.Option(False, "--json", help="Print JSON instead of lines.")) -> None:
    """Measure in a terrain run's halftone model: ground coordinates, heights, distances, slopes and
    areas, each with its standard deviation from the refined orientation's covariance."""
    from workbench import api

    found = api.measure(model, points=point, lines=line, polygons=polygon)
    if as_json:
        typer.echo(json.dumps([m.to_json() for m in found], indent=1))
    else:
        typer.echo("\n".join(m.text() for m in found))


@app.command("list")
def list_experiments() -> None:
    """Name the experiments, their scenarios and estimators (installed plugins too)."""
    from workbench.experiments.estimator import installed

    for exp in experiments.all_experiments():
        typer.echo(f"{exp.name:8s} {exp.description}")
        typer.echo(f"  scenarios:  {', '.join(exp.scenarios)}")
        extra = list(installed(exp.name))
        typer.echo(f"  estimators: {', '.join(exp.estimators)}" + (f"; plugins: {', '.join(extra)}" if extra else ""))


@app.command()
@friendly
def demo(force: bool = typer.Option(False, help="Overwrite existing recordings."),
         runs: int = typer.Option(20, help="Monte Carlo runs per experiment (some steps take fewer).")) -> None:
    """Run every experiment's demo steps on their defaults; recordings go to recordings/.
    A step is skipped only where its real data is absent; any other error fails the demo."""
    written = []
    for exp in experiments.all_experiments():
        for step in exp.demo:
            n = min(runs, step.max_runs or runs)
            try:
                res = execute(exp, step.scenario, RECORDINGS / f"{step.name}.rrd", force,
                              RECORDINGS / f"{step.name}.json", estimators=step.estimators, quiet=True, runs=n,
                              **step.overrides)
            except DataNotFound as exc:
                if not exp.scenarios[step.scenario].real_data:
                    raise
                typer.echo(f"{step.name:16s} skipped: {exc}")
                continue
            written.append(res.recording)
            typer.echo(f"{step.name:16s} -> {res.recording}  ({res.metrics['wall_seconds']:.1f} s, {n} run(s))")
    if written:
        typer.echo(f"\nrecordings in {RECORDINGS}; open one with: workbench view {written[0]}")


@app.command()
@friendly
def view(
    file: Path = typer.Argument(..., help="A .rrd recording."),
    web: bool = typer.Option(False, help="Serve the web viewer even where a display exists."),
    port: int = typer.Option(9090, help="Web viewer port (1024-65535)."),
    host: str = typer.Option("127.0.0.1", help="Address the web viewer binds to (0.0.0.0: every interface)."),
) -> None:
    """Open a recording: the native viewer where a display exists, else the web viewer (on
    localhost unless --host says otherwise). Exits with the viewer's exit code."""
    from workbench.recording import readback

    readback.check_recording(file)
    exe = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    has_display = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                       or sys.platform in ("darwin", "win32"))
    if has_display and not web:
        raise typer.Exit(subprocess.run([exe, str(file)], check=False).returncode)
    if not 1024 <= port <= 65535:
        raise WorkbenchError(f"--port must be in 1024..65535, got {port}")
    _port_free(host, port)
    typer.echo(f"serving the web viewer at http://{'localhost' if host == '127.0.0.1' else host}:{port} "
               "(Ctrl-C to stop)")
    code = subprocess.run([exe, "--web-viewer", "--web-viewer-port", str(port), "--bind", host, str(file)],
                          check=False).returncode
    raise typer.Exit(code)


def _port_free(host: str, port: int) -> None:
    """A one-line error unless ``host:port`` can be bound now (busy, or not an address here)."""
    import socket

    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise WorkbenchError(f"--host {host!r} is not an address: {exc.strerror}") from None
    family, _, _, _, address = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:
        try:
            s.bind(address)
        except OSError as exc:
            raise WorkbenchError(f"cannot serve on {host}:{port}: {exc.strerror} (busy? choose --port)") from None
