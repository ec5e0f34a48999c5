"""A sweep's unit of work: one cell's chunk of Monte Carlo runs, as a picklable :class:`Task`
that any executor (a local process pool, a Dask worker) runs with :func:`run_task`, through the
experiment's contract, into a tidy table: one row per run x estimator x metric.

Seeds: run k of every cell draws from ``(seed, k)``, whatever worker or order runs it. The cells
share their random numbers (common random numbers), so what differs between two cells is the
parameter, not the noise; a cell's own settings (a noise level, a window) act on those draws.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

COLUMNS = ("experiment", "scenario", "cell", "run", "estimator", "metric", "value", "unit", "failed",
           "config_hash", "seed", "version", "git_commit")
"""The tidy table's fixed columns; each swept setting adds one column named ``p.<setting>``."""


@dataclass(frozen=True)
class Task:
    """Runs ``start .. stop-1`` of cell ``cell`` (settings ``params`` on top of ``fixed``)."""

    experiment: str
    scenario: str | None
    cell: int
    params: tuple[tuple[str, Any], ...]
    fixed: tuple[tuple[str, Any], ...]
    start: int
    stop: int
    seed: int
    estimators: tuple[Any, ...]
    version: str = ""
    git_commit: str = ""
    preset: str | None = None

    @property
    def file(self) -> str:
        return f"cell{self.cell:04d}-runs{self.start:06d}-{self.stop:06d}.parquet"

    def config(self):
        """The cell's config (its own scenario if the grid sweeps scenarios)."""
        from workbench.core.registry import get
        from workbench.sweeps.grid import expand

        exp = get(self.experiment)
        given = {**dict(self.fixed), **expand(exp, dict(self.params))}
        scenario = given.pop("scenario", self.scenario)
        return exp.validate(exp.configure(scenario, seed=self.seed, runs=max(1, self.stop), **given))


def config_hash(cfg: Any) -> str:
    """A short hash of everything a cell's runs depend on (the run count aside)."""
    d = dict(cfg.to_json())
    d.pop("runs", None)
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]


def run_task(task: Task) -> pa.Table:
    """The task's runs, every estimator on each, as tidy rows (``failed`` rows name an
    estimator that failed in a run, with the reason in ``unit``)."""
    import socket
    import time

    from workbench.core.registry import get

    t0 = time.perf_counter()
    exp = get(task.experiment)
    cfg = task.config()
    if cfg.tune_noise:  # a cell that tunes its noise on its run 0's data first, as a run of the command does
        from workbench.core import selftune

        cfg = dataclasses.replace(selftune.tune_noise(exp, cfg)[0], tune_noise=False)
    chosen = exp.select(list(task.estimators))
    cfg.estimators = tuple(e.spec for e in chosen)
    units = exp.metric_units(cfg)
    rows: dict[str, list] = {c: [] for c in COLUMNS}
    params = dict(task.params)
    for key in params:
        rows[f"p.{key}"] = []
    digest = config_hash(cfg)

    def add(run: int, estimator: str, metric: str, value: float, unit: str, failed: bool) -> None:
        for c, v in (("experiment", task.experiment), ("scenario", cfg.scenario), ("cell", task.cell), ("run", run),
                     ("estimator", estimator), ("metric", metric), ("value", value), ("unit", unit),
                     ("failed", failed), ("config_hash", digest), ("seed", task.seed), ("version", task.version),
                     ("git_commit", task.git_commit)):
            rows[c].append(v)
        for key, v in params.items():
            rows[f"p.{key}"].append(v)

    for run in range(task.start, task.stop):
        summary = exp.evaluate(exp.run_once(cfg, run, chosen), cfg, run)
        for name, figures in exp.run_metrics(summary, cfg).items():
            for metric, value in figures.items():
                add(run, name, metric, float(value), units.get(metric, ""), False)
        for name, why in summary.failed.items():
            add(run, name, "failed", float("nan"), why, True)
    meta = {"experiment": task.experiment, "scenario": task.scenario, "fixed": dict(task.fixed),
            "grid": [k for k, _ in task.params], "estimators": list(task.estimators), "preset": task.preset,
            "seconds": time.perf_counter() - t0, "worker": f"{socket.gethostname()}:{os.getpid()}"}
    return pa.table(rows).replace_schema_metadata({b"workbench.sweep": json.dumps(meta, default=str).encode()})


def write(table: pa.Table, folder: Path, name: str) -> Path:
    """Write a task's table to ``folder/name`` atomically (a temporary name, then a rename)."""
    path = Path(folder) / name
    tmp = path.with_name(f".{name}.{os.getpid()}.tmp")
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    except BaseException:  # (Ctrl-C mid-write too: a half-written temporary is not left behind)
        tmp.unlink(missing_ok=True)
        raise
    return path
