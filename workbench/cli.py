"""The ``workbench`` launcher: a thin typer layer over :func:`workbench.api.run`.

One command per registered experiment, built from its contract by one code path
(:mod:`workbench.experiment_command`), and the commands an experiment declares;
plus ``list``, ``demo``, the tools (``view``, ``info``, ``replay``, ``screenshot``, ``compare``:
:mod:`workbench.tools.cli`) and ``sweep`` / ``sweep-report`` (:mod:`workbench.sweeps.cli`).
Nothing here knows an experiment's settings.
"""

from __future__ import annotations

import os

# The estimators multiply small matrices: BLAS threads only add overhead, and Monte Carlo
# runs already use both cores. Set before numpy is first imported.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys
from collections.abc import Callable
from functools import wraps
from pathlib import Path

import typer

from workbench import experiment_command as commands
from workbench import loading
from workbench.core import registry as experiments
from workbench.errors import DataNotFound, WorkbenchError
from workbench.experiment_command import RECORDINGS, execute
from workbench.sweeps import cli as sweep_commands
from workbench.tools import cli as tool_commands
from workbench.tuning import cli as tune_commands

app = typer.Typer(no_args_is_help=True, add_completion=False,
                  help="Estimation workbench: paper estimators against GTSAM, recorded to Rerun.")


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


for _exp in experiments.all_experiments():
    app.command(_exp.name)(commands.command(_exp, friendly))
    for _cmd in _exp.commands:
        app.command(_cmd.name)(friendly(_cmd.cli()))
app.command("sweep")(friendly(sweep_commands.sweep))
app.command("sweep-report")(friendly(sweep_commands.sweep_report))
app.command("tune")(friendly(tune_commands.tune))
for _name in ("info", "replay", "screenshot", "compare", "view"):
    app.command(_name)(friendly(getattr(tool_commands, _name)))


@app.command("list")
def list_experiments() -> None:
    """Name the experiments, their scenarios and estimators (installed plugins too)."""
    from workbench.core.estimator import installed

    for exp in experiments.all_experiments():
        typer.echo(f"{exp.name:8s} {exp.description}")
        typer.echo(f"  scenarios:  {', '.join(exp.scenarios)}")
        extra = list(installed(exp.name))
        typer.echo(f"  estimators: {', '.join(exp.estimators)}" + (f"; plugins: {', '.join(extra)}" if extra else ""))


@app.command()
@friendly
def demo(force: bool = typer.Option(False, help="Overwrite existing recordings."),
         runs: int = typer.Option(20, help="Monte Carlo runs per experiment (some steps take fewer)."),
         only: str = typer.Option(None, help="Comma-separated experiments to run [every one, installed ones too]."),
         out: str = typer.Option(None, help="The folder for the recordings and metrics [recordings/].")) -> None:
    """Run every experiment's demo steps on their defaults; recordings go to recordings/.
    A step is skipped only where its real data is absent; any other error fails the demo."""
    written = []
    folder = RECORDINGS if out is None else Path(out)
    if not str(out if out is not None else folder).strip():
        raise WorkbenchError("--out needs a folder name, got ''")
    chosen = experiments.all_experiments() if only is None else \
        [experiments.get(n) for n in loading.split_list(only) or [""]]
    for exp in chosen:
        for step in exp.demo:
            n = min(runs, step.max_runs or runs)
            try:
                res = execute(exp, step.scenario, folder / f"{step.name}.rrd", force, folder / f"{step.name}.json",
                              estimators=step.estimators, quiet=True, runs=n, **step.overrides)
            except DataNotFound as exc:
                if not exp.scenarios[step.scenario].real_data:
                    raise
                typer.echo(f"{step.name:16s} skipped: {exc}")
                continue
            written.append(res.recording)
            typer.echo(f"{step.name:16s} -> {res.recording}  ({res.metrics['wall_seconds']:.1f} s, {n} run(s))")
    if written:
        typer.echo(f"\nrecordings in {folder}; open one with: workbench view {written[0]}")


