"""``workbench sweep`` and ``workbench sweep-report``: the command line's thin layer over
:func:`.runner.sweep` and :func:`.report.write` (registered by :mod:`workbench.cli`)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from workbench.errors import WorkbenchError

INTERRUPTED = 130


def sweep(
    experiment: str = typer.Argument(..., help="The experiment: omni | sea | terrain."),
    grid: list[str] = typer.Option(None, "--grid", help="KEY=V1,V2,... over a setting (repeat for a product)."),
    preset: str = typer.Option(None, help="A named grid of the experiment (see --list-presets)."),
    list_presets: bool = typer.Option(False, "--list-presets", help="Name the experiment's presets and stop."),
    fixed: list[str] = typer.Option(None, "--set", help="KEY=VALUE for every cell (repeatable)."),
    scenario: str = typer.Option(None, help="The scenario \\[the experiment's first, or the preset's]."),
    config: str = typer.Option(None, help="A TOML or JSON file of settings for every cell (as the experiment's "
                                          "--config), beneath the preset, --set and --grid."),
    runs: int = typer.Option(None, help="Monte Carlo runs per cell \\[the config file's, or 10]."),
    seed: int = typer.Option(None, help="Run k of every cell draws from (seed, k) \\[the config file's, or 0]."),
    estimators: str = typer.Option(None, help="As for the experiment's command \\[its defaults, or the preset's]."),
    out: str = typer.Option(None, help="The sweep folder \\[sweeps/<experiment>]."),
    force: bool = typer.Option(False, help="Start the sweep in --out again, deleting its results."),
    resume: bool = typer.Option(False, help="Finish the sweep in --out: run only the tasks not on disk."),
    chunk: int = typer.Option(None, help="Runs per task \\[about 8 tasks per worker, at most 50]."),
    jobs: int = typer.Option(None, help="Local pool: processes \\[up to 2]."),
    scheduler: str = typer.Option(None, help="A Dask scheduler's address, tcp://HOST:PORT: run the tasks there."),
    local_cluster: int = typer.Option(None, help="Start a Dask LocalCluster of this many workers for the sweep."),
) -> None:
    """Sweep an experiment over a grid of settings: Monte Carlo runs per cell, on a local pool
    or a Dask cluster; tidy Parquet rows, a summary, plots and a recording in --out."""
    from workbench.core.registry import get
    from workbench.paths import PROJECT_ROOT
    from workbench.sweeps import grid as grids
    from workbench.sweeps import runner

    exp = get(experiment)
    if list_presets:
        for p in exp.presets:
            keys = " x ".join(f"{k} ({len(v)})" for k, v in p.grid.items())
            typer.echo(f"{p.name:16s} {p.description}: {keys}")
        return
    from workbench.config import files as configfile

    overrides = configfile.loads(exp, config) if config is not None else {}
    from_file = overrides.pop("scenario", None)
    scenario = from_file if scenario is None else scenario
    runs = runs if runs is not None else overrides.pop("runs", 10)
    seed = seed if seed is not None else overrides.pop("seed", 0)
    listed = overrides.pop("estimators", ())
    spec, chosen = {}, estimators or (",".join(listed) if listed else None)
    for name in grids.FIXED:
        overrides.pop(name, None)
    if preset is not None:
        found = {p.name: p for p in exp.presets}
        if preset not in found:
            raise WorkbenchError(f"{exp.name} has no preset {preset!r}; its presets: {', '.join(found) or 'none'}")
        p = found[preset]
        spec = {k: tuple(v) for k, v in p.grid.items()}
        overrides.update(p.overrides)
        scenario = p.scenario if scenario is None else scenario
        chosen = chosen or p.estimators
    spec.update(grids.parse(exp, grid or []))
    for name in spec:  # the grid sets these in every cell: the file's or the preset's value is not fixed
        for f in grids.expand(exp, {name: None}):
            overrides.pop(f, None)
    overrides.update(grids.settings(exp, fixed or []))
    if not spec:
        raise WorkbenchError("nothing to sweep: give --grid KEY=V1,V2,... or --preset NAME")
    if out is not None and (not out.strip() or Path(out).resolve() == Path.cwd().resolve()):
        raise WorkbenchError(f"--out {out!r}: name a folder of its own for the sweep (--force empties it)")
    folder = Path(out) if out is not None else PROJECT_ROOT / "sweeps" / exp.name
    bar, task = _progress()
    with bar:
        res = runner.sweep(exp.name, scenario, spec, overrides, runs, seed, tuple(_names(chosen)), folder, chunk,
                           jobs, scheduler, local_cluster, resume, force, preset,
                           progress=lambda done, total: bar.update(task, completed=done, total=total))
    line = (f"{res.tasks} task(s) on {res.executor}: {res.done_before} done before, {res.computed} computed "
            f"in {res.seconds:.1f} s")
    if res.interrupted:
        typer.echo(f"interrupted: {line}; the finished ones are kept in {res.out}; "
                   f"run the same command with --resume to finish", err=True)
        raise typer.Exit(INTERRUPTED)
    for note in res.notes:
        typer.echo(f"note: {note}", err=True)
    typer.echo((res.out / "summary.md").read_text())
    pngs = sum(p.suffix == ".png" for p in res.written)
    others = [p.name for p in res.written if p.suffix != ".png"]
    typer.echo(f"\n{line}\nwritten: {res.out}/ ({', '.join(others)}, {pngs} PNG(s), tasks/*.parquet)")


def sweep_report(folder: Path = typer.Argument(..., help="A sweep folder (its tasks/*.parquet).")) -> None:
    """Rebuild a sweep's summary, plots and recording from its Parquet files alone."""
    from workbench.sweeps import report

    written = report.write(folder)
    typer.echo("\n".join(str(p) for p in written))


def _names(selection: str | None) -> list[str]:
    from workbench.loading import split_list

    return list(split_list(selection)) if selection else []


def _progress():
    """A progress bar over tasks with an ETA (rich, which typer brings), on a terminal only."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    bar = Progress(TextColumn("sweep"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), TextColumn("eta"),
                   TimeRemainingColumn(), transient=True, disable=not sys.stderr.isatty())
    return bar, bar.add_task("tasks", total=None)
