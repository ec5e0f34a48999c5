"""``workbench tune``: the command line's thin layer over :func:`.study.tune` (registered by
:mod:`workbench.cli`)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from workbench.errors import WorkbenchError

INTERRUPTED = 130


def tune(
    experiment: str = typer.Argument(..., help="The experiment: omni | sea | terrain."),
    param: list[str] = typer.Option(None, "--param", help="NAME=LOW:HIGH[:log]: a number setting to search "
                                    "(repeat for several); a noise is tuned as what the estimators assume."),
    objective: str = typer.Option("likelihood", help="likelihood (no truth used) | nees | rmse | a metric's name."),
    estimator: str = typer.Option(None, help="Whose objective: a built-in or a plugin \\[the first filter]."),
    estimators: str = typer.Option(None, help="Run these in each trial too (their rows are kept) \\[--estimator "
                                              "alone]."),
    trials: int = typer.Option(50, help="Trials in the study (a resumed study may be given more)."),
    runs: int = typer.Option(5, help="Monte Carlo runs per trial (the same runs in every trial)."),
    batch: int = typer.Option(None, help="Trials asked at once \\[twice the workers]."),
    scenario: str = typer.Option(None, help="The scenario \\[the config file's, or the experiment's first]."),
    config: str = typer.Option(None, help="A TOML or JSON file of settings for every trial (as --config)."),
    fixed: list[str] = typer.Option(None, "--set", help="KEY=VALUE for every trial (repeatable)."),
    seed: int = typer.Option(0, help="The runs' seed and the sampler's."),
    out: str = typer.Option(None, help="The study's folder \\[tune/<experiment>]."),
    force: bool = typer.Option(False, help="Start the study in --out again, deleting its results."),
    resume: bool = typer.Option(False, help="Go on with the study in --out (after Ctrl-C or a kill)."),
    jobs: int = typer.Option(None, help="Local pool: processes \\[up to 2]."),
    scheduler: str = typer.Option(None, help="A Dask scheduler's address, tcp://HOST:PORT: run the trials there."),
    local_cluster: int = typer.Option(None, help="Start a Dask LocalCluster of this many workers for the study."),
) -> None:
    """Tune an experiment's settings (its noise model) by the likelihood of the measurements (no truth
    needed), NEES consistency or an error, with Optuna; trials on a local pool or a Dask cluster."""
    from workbench.config import files as configfile
    from workbench.core.registry import get
    from workbench.loading import split_list
    from workbench.paths import PROJECT_ROOT
    from workbench.sweeps import grid as grids
    from workbench.tuning import space, study

    exp = get(experiment)
    base = configfile.loads(exp, config) if config is not None else {}
    from_file = base.pop("scenario", None)
    scenario = from_file if scenario is None else scenario
    listed = base.pop("estimators", ())
    for name in ("seed", "runs"):
        base.pop(name, None)
    base.update(grids.settings(exp, fixed or []))
    params = space.parse(exp, list(param or []), base, scenario)
    if out is not None and (not out.strip() or Path(out).resolve() == Path.cwd().resolve()):
        raise WorkbenchError(f"--out {out!r}: name a folder of its own for the study (--force empties it)")
    folder = Path(out) if out is not None else PROJECT_ROOT / "tune" / exp.name
    chosen = tuple(split_list(estimators)) if estimators else tuple(listed)
    bar, task = _progress()
    with bar:
        res = study.tune(exp.name, params, objective, estimator, trials, runs, seed, batch, folder, scenario, base,
                         chosen, jobs, scheduler, local_cluster, resume, force,
                         progress=lambda done, total, best: bar.update(task, completed=done, total=total,
                                                                       best=f"{best:.6g}"))
    line = (f"{res.trials} trial(s) on {res.executor}: {res.done_before} done before, {res.computed} run "
            f"in {res.seconds:.1f} s (the tuner's own share {res.tuner_seconds:.2f} s)")
    if res.interrupted:
        typer.echo(f"interrupted: {line}; every finished trial is kept in {res.out}; "
                   "run the same command with --resume to go on", err=True)
        raise typer.Exit(INTERRUPTED)
    for note in res.notes:
        typer.echo(f"note: {note}", err=True)
    typer.echo((res.out / "summary.md").read_text())
    typer.echo(f"{line}\nwritten: {res.out}/ (best.toml, summary.md, study.rrd, PNGs, trials/*.parquet)")


def _progress():
    """A progress bar over trials with the best objective so far, on a terminal only."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    bar = Progress(TextColumn("tune"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   TextColumn("best {task.fields[best]}"), transient=True, disable=not sys.stderr.isatty())
    return bar, bar.add_task("trials", total=None, best="-")
