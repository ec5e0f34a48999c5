"""Monte Carlo runs over processes, shared by every experiment.

``worker(run) -> summary`` (picklable: a module-level function or a ``functools.partial`` of
one) gives one run's summary, which has a ``run`` attribute; run 0 may be given already
computed (the recorded run). Runs are independent and seeded by ``(seed, run)`` inside the
worker, so the result does not depend on the number of processes.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any


def worker_init() -> None:
    """Each worker process: Ctrl-C (sent to the whole process group) is the parent's to handle,
    so the workers print no tracebacks; and on Linux a worker is sent SIGTERM when its parent
    dies (``prctl(PR_SET_PDEATHSIG)``), so no worker outlives a killed run."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
        if os.getppid() == 1:  # the parent died before the line above
            os._exit(1)
    except (OSError, AttributeError):
        pass


def pool(jobs: int) -> ProcessPoolExecutor:
    """A process pool of ``jobs`` workers set up by :func:`worker_init`."""
    return ProcessPoolExecutor(max_workers=jobs, initializer=worker_init)


def stop(executor: ProcessPoolExecutor) -> None:
    """End a pool now: queued runs cancelled, running workers terminated (an interrupt or an
    error in the parent must not wait for them, nor leave them behind)."""
    procs = list((getattr(executor, "_processes", None) or {}).values())
    for p in procs:
        if p.is_alive():
            p.terminate()
    for p in procs:
        p.join(timeout=5)
    # the pool's manager thread sees its workers gone and ends; waiting for it here keeps
    # the interpreter's exit hook from writing to a closed pipe
    executor.shutdown(wait=True)


def _chunk(worker: Callable[[int], Any], runs: list[int]) -> list:
    return [worker(r) for r in runs]


def run_all(worker: Callable[[int], Any], runs: int, first: Any = None, jobs: int | None = None,
            progress: Callable[[int], None] | None = None) -> list:
    """Summaries of runs ``0 .. runs-1``, sorted by run; ``first`` is run 0's summary if given.

    Runs go to the workers in chunks of about an eighth of each worker's share, so short runs
    do not pay a round trip each and long ones still balance."""
    out: list = []
    todo = list(range(runs))
    if first is not None:
        out.append(first)
        todo = todo[1:]
        if progress:
            progress(1)
    jobs = jobs or min(2, os.cpu_count() or 1)
    if len(todo) <= 1 or jobs == 1:
        for r in todo:
            out.append(worker(r))
            if progress:
                progress(1)
    else:
        chunk = max(1, len(todo) // (8 * jobs))
        executor = pool(jobs)
        try:
            futures = [executor.submit(_chunk, worker, todo[i:i + chunk]) for i in range(0, len(todo), chunk)]
            for f in as_completed(futures):
                done = f.result()
                out.extend(done)
                if progress:
                    progress(len(done))
        except BaseException:
            stop(executor)
            raise
        executor.shutdown(wait=True)
    return sorted(out, key=lambda s: s.run)
