"""Speed of sweeps (targets from issue 11): 1,000 sea paper runs in one sweep in under 4 minutes
on the 2-core machine with the overhead under 5 % of the compute; the per-task overhead of the
local pool and of Dask against the run time; the speed-up from 1 to 2 workers; the Dask
scheduler's throughput and the data per task, for the README's projection to a cluster.

Run: ``python benchmarks/bench_sweep.py [--quick]``. Compute is what the tasks report they took
(each task's Parquet file carries its own seconds); overhead is the rest of workers x wall time
(process start, planning, shipping tasks and rows, writing files, the report). The load
average is printed beside each figure: on a shared machine compare the ratios of one run.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

import pyarrow.parquet as pq

from workbench.sweeps import runner


def task_seconds(folder: Path) -> tuple[float, int, int]:
    """Total compute the tasks reported, their count, and the bytes of their files."""
    files = sorted((folder / "tasks").glob("*.parquet"))
    total = sum(json.loads(pq.read_schema(f).metadata[b"workbench.sweep"])["seconds"] for f in files)
    return total, len(files), sum(f.stat().st_size for f in files)


def sweep(folder: Path, runs: int, workers: int, dask: bool = False, chunk: int | None = None,
          duration: float | None = None, report: bool = True) -> dict:
    fixed = {"duration": duration} if duration else {}
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    runner.sweep("sea", None, {"lam": (1.0,)}, fixed, runs=runs, out=folder, chunk=chunk,
                 jobs=None if dask else workers, local_cluster=workers if dask else None, report=report)
    wall = time.perf_counter() - t0
    compute, tasks, size = task_seconds(folder)
    return {"wall": wall, "compute": compute, "tasks": tasks, "bytes": size, "load": load, "workers": workers,
            "overhead": 1.0 - compute / (workers * wall), "per_task_ms": 1e3 * (workers * wall - compute) / tasks}


def show(label: str, r: dict) -> None:
    print(f"{label:46s} wall {r['wall']:6.1f} s, compute {r['compute']:6.1f} s over {r['tasks']} task(s), overhead "
          f"{100 * r['overhead']:4.1f} % ({r['per_task_ms']:.0f} ms a task), {r['bytes'] / r['tasks'] / 1e3:.1f} kB "
          f"a task, load {r['load']:.1f}")


def scheduler_rate(n: int = 2000) -> float:
    """Trivial tasks per second through a 2-worker LocalCluster: the scheduler's own ceiling here."""
    from concurrent.futures import as_completed

    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster, Client(cluster) as client:
        ex = client.get_executor()
        t0 = time.perf_counter()
        for f in as_completed([ex.submit(abs, -i) for i in range(n)]):
            f.result()
        return n / (time.perf_counter() - t0)


def main() -> None:
    quick = "--quick" in sys.argv
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        big = 200 if quick else 1000
        r = sweep(d / "big", big, 2)
        show(f"{big} sea paper runs, local pool, 2 workers", r)
        print(f"  target: 1,000 runs under 240 s with the overhead under 5 %; runs/s {big / r['wall']:.1f}")
        one = sweep(d / "one", 100, 1)
        two = sweep(d / "two", 100, 2)
        show("100 runs, local pool, 1 worker", one)
        show("100 runs, local pool, 2 workers", two)
        print(f"  speed-up 1 -> 2 workers (pool): {one['wall'] / two['wall']:.2f}")
        d1 = sweep(d / "d1", 100, 1, dask=True)
        d2 = sweep(d / "d2", 100, 2, dask=True)
        show("100 runs, Dask LocalCluster, 1 worker", d1)
        show("100 runs, Dask LocalCluster, 2 workers", d2)
        print(f"  speed-up 1 -> 2 workers (Dask): {d1['wall'] / d2['wall']:.2f}")
        for dask in (False, True):
            small = sweep(d / f"small{dask}", 200, 2, dask=dask, chunk=1, duration=2.0, report=False)
            show(f"200 one-run tasks of 2 s runs, {'Dask' if dask else 'pool'}", small)
        print(f"Dask scheduler, trivial tasks: {scheduler_rate():.0f} tasks/s (2 workers on loopback)")


if __name__ == "__main__":
    main()
