"""Running a sweep: the cells x chunks of runs as tasks on an executor, each finished task's
rows written at once to its own Parquet file (atomically), so a sweep killed midway keeps every
finished task and ``resume`` computes only the rest.

One submit / ``as_completed`` loop serves every executor: a local process pool (the default),
a Dask cluster given by its scheduler's address (``distributed.Client(address).get_executor()``),
or a ``distributed.LocalCluster`` started for the sweep. The results do not depend on which:
a run's seed is ``(seed, run)`` (:mod:`.tasks`).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from collections.abc import Callable, Iterator, Mapping
from concurrent.futures import Executor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from workbench.config import checks as limits
from workbench.core import montecarlo
from workbench.core.registry import get
from workbench.errors import WorkbenchError
from workbench.sweeps import grid as grids
from workbench.sweeps.tasks import Task, run_task, write
from workbench.version import __version__

MANIFEST = "sweep.json"
TASKS = "tasks"
MAX_CHUNK = 50


@dataclass
class SweepResult:
    out: Path
    tasks: int                        # in the whole sweep
    done_before: int                  # finished before this call (resume)
    computed: int = 0                 # finished by this call
    seconds: float = 0.0
    interrupted: bool = False
    executor: str = ""
    written: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # what the experiment said expanding the grid (ships left out)


@contextmanager
def executor(jobs: int | None = None, scheduler: str | None = None,
             local_cluster: int | None = None) -> Iterator[tuple[Executor, str, int]]:
    """``(executor, description, workers)``: a local pool, a Dask cluster, or a local Dask cluster."""
    if scheduler and local_cluster:
        raise WorkbenchError("give --scheduler or --local-cluster, not both")
    if scheduler or local_cluster:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise WorkbenchError("Dask is not installed: pip install distributed") from None
        cluster = None
        try:
            if local_cluster:
                cluster = LocalCluster(n_workers=local_cluster, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=None)
                client = Client(cluster)
            else:
                client = Client(scheduler, timeout="5s")
        except (OSError, TimeoutError) as exc:
            if cluster is not None:
                cluster.close()
            raise WorkbenchError(f"cannot reach the Dask scheduler at {scheduler}: {type(exc).__name__}: "
                                 f"{str(exc).splitlines()[0] if str(exc) else ''}") from None
        try:
            workers = max(1, len(client.scheduler_info().get("workers", {})))
            where = f"local Dask cluster ({local_cluster} workers)" if local_cluster else f"Dask at {scheduler}"
            yield client.get_executor(), f"{where}, {workers} worker(s)", workers
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        return
    jobs = jobs or min(2, os.cpu_count() or 1)
    limits.check_jobs(jobs)
    local = montecarlo.pool(jobs)
    try:
        yield local, f"local pool, {jobs} process(es)", jobs
    except BaseException:
        montecarlo.stop(local)
        raise
    local.shutdown(wait=True)


def chunk_size(runs: int, cells: int, workers: int, given: int | None = None) -> int:
    """Runs per task: about eight tasks per worker over the sweep, at most ``MAX_CHUNK`` runs
    (a task is then seconds to minutes: its ~2 ms of overhead is lost in it, and the load
    still balances)."""
    if given is not None:
        if given < 1:
            raise WorkbenchError(f"--chunk must be at least 1 (got {given})")
        return given
    return max(1, min(MAX_CHUNK, runs, math.ceil(runs * cells / (8 * workers)) if cells else runs))


def plan(experiment: str, scenario: str | None, grid: Mapping[str, tuple], fixed: Mapping[str, Any], runs: int,
         seed: int, estimators: tuple, chunk: int, preset: str | None = None) -> list[Task]:
    """Every task of the sweep, each cell's config built and validated first (one-line errors)."""
    from workbench.recording.stream import git_commit

    exp = get(experiment)
    if runs < 1:
        raise WorkbenchError(f"--runs must be at least 1 (got {runs})")
    if seed < 0:
        raise WorkbenchError(f"--seed must not be negative (got {seed})")
    chosen = exp.select(estimators if estimators else None)
    refs = tuple(e.spec for e in chosen)
    if any(e.ref is None for e in chosen):
        raise WorkbenchError("a sweep's estimators must be names or module:function / file.py:function specs")
    commit = git_commit() or "unknown"
    tasks = []
    for c, cell in enumerate(grids.cells(grid)):
        params = tuple(cell.items())
        probe = Task(experiment, scenario, c, params, tuple(fixed.items()), 0, runs, seed, refs)
        cfg = probe.config()  # validates the cell (a one-line error names the bad value)
        if exp.run_count(cfg) != cfg.runs:
            raise WorkbenchError(f"{experiment}: these settings make {exp.run_count(cfg)} runs of each cell's "
                                 f"{cfg.runs} (several cases per run); a sweep counts its runs itself: sweep the "
                                 "cases as a grid (e.g. --grid mmsi=all)")
        for start in range(0, runs, chunk):
            tasks.append(Task(experiment, scenario, c, params, tuple(fixed.items()), start, min(runs, start + chunk),
                              seed, refs, __version__, commit, preset))
    return tasks


def _manifest(experiment: str, scenario: str | None, grid: Mapping[str, tuple], fixed: Mapping[str, Any], runs: int,
              seed: int, refs: tuple, chunk: int, preset: str | None) -> dict:
    return json.loads(json.dumps({"experiment": experiment, "scenario": scenario, "preset": preset,
                                  "grid": {k: list(v) for k, v in grid.items()}, "fixed": dict(fixed),
                                  "runs": runs, "seed": seed, "estimators": list(refs), "chunk": chunk},
                                 default=str))


def prepare(out: Path, manifest: dict, resume: bool, force: bool, what: str = "sweep", name: str = MANIFEST,
            sub: str = TASKS, kinds: tuple[str, ...] = ("*.png", "*.md", "*.csv", "*.rrd"),
            loose: tuple[str, ...] = ("preset",)) -> Path:
    """The sweep folder (or a tuning study's: ``what``, its manifest ``name``, results folder
    ``sub``, the kinds of file it writes), checked: a new one; or, with ``resume``, the same
    sweep's (its manifest equal but for the keys ``loose``); or, with ``force``, the same folder
    emptied of a sweep's files. Anything else is a one-line error, and nothing is touched."""
    out = Path(out).expanduser()
    if resume and force:
        raise WorkbenchError("give --resume or --force, not both")
    if out.exists() and not out.is_dir():
        raise WorkbenchError(f"{out} is a file, not a {what} folder")
    existing = out / name
    if out.is_dir() and any(out.iterdir()):
        if not existing.is_file():
            raise WorkbenchError(f"{out} exists and holds no {what}; choose another --out")
        if resume:
            before = json.loads(existing.read_text())
            keys = [k for k in manifest if k not in loose and before.get(k) != manifest[k]]
            if keys:
                raise WorkbenchError(f"{out} holds another {what} (its {', '.join(keys)} differ); "
                                     "resume it with its own settings, or --force a new one")
        elif force:  # a sweep folder: the kinds of file a sweep writes go
            shutil.rmtree(out / sub, ignore_errors=True)
            for kind in (*kinds, name):
                for path in out.glob(kind):
                    path.unlink()
        else:
            raise WorkbenchError(f"{out} holds a {what}; pass --resume to finish it or --force to start again")
    elif resume:
        raise WorkbenchError(f"nothing to resume in {out}")
    try:
        (out / sub).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WorkbenchError(f"cannot create {out}: {exc.strerror}") from None
    if not os.access(out, os.W_OK):
        raise WorkbenchError(f"cannot write to {out}")
    from workbench.recording.stream import write_text_atomic

    write_text_atomic(out / name, json.dumps(manifest, indent=2))
    return out


def sweep(experiment: str, scenario: str | None = None, grid: Mapping[str, tuple] | None = None,
          fixed: Mapping[str, Any] | None = None, runs: int = 10, seed: int = 0, estimators: tuple = (),
          out: Path = Path("sweep"), chunk: int | None = None, jobs: int | None = None, scheduler: str | None = None,
          local_cluster: int | None = None, resume: bool = False, force: bool = False, preset: str | None = None,
          progress: Callable[[int, int], None] | None = None, report: bool = True) -> SweepResult:
    """Run every cell x chunk of runs not yet on disk; write the report when all are."""
    grid, fixed = dict(grid or {}), dict(fixed or {})
    exp, notes = get(experiment), []
    for key, values in list(grid.items()):  # the experiment's own expansions (sea: mmsi=all -> every usable ship)
        grid[key], said = exp.grid_values(key, tuple(values), scenario, fixed)
        notes += said
    n_cells = len(grids.cells(grid))
    progress = progress or (lambda done, total: None)
    t0 = time.perf_counter()
    with executor(jobs, scheduler, local_cluster) as (pool, where, workers):
        size = chunk_size(runs, n_cells, workers, chunk)
        tasks = plan(experiment, scenario, grid, fixed, runs, seed, estimators, size, preset)
        folder = prepare(out, _manifest(experiment, scenario, grid, fixed, runs, seed, tasks[0].estimators, size,
                                        preset), resume, force)
        for stale in (folder / TASKS).glob(".*.tmp"):   # a write a SIGKILL cut short: its task is redone
            stale.unlink(missing_ok=True)
        done = {p.name for p in (folder / TASKS).glob("*.parquet")}
        todo = [t for t in tasks if t.file not in done]
        result = SweepResult(folder, len(tasks), len(tasks) - len(todo), executor=where, notes=notes)
        progress(result.done_before, len(tasks))
        futures = {pool.submit(run_task, t): t for t in todo}
        try:
            for fut in as_completed(futures):
                task = futures[fut]
                write(fut.result(), folder / TASKS, task.file)
                result.computed += 1
                progress(result.done_before + result.computed, len(tasks))
        except KeyboardInterrupt:
            for f in futures:
                f.cancel()
            result.interrupted = True
    result.seconds = time.perf_counter() - t0
    if report and not result.interrupted:
        from workbench.sweeps import report as reports

        result.written = reports.write(folder)
    return result
