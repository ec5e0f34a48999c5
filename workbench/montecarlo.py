"""Monte Carlo runs over processes, shared by every experiment.

``worker(run) -> summary`` (picklable: a module-level function or a ``functools.partial`` of
one) gives one run's summary, which has a ``run`` attribute; run 0 may be given already
computed (the recorded run). Runs are independent and seeded by ``(seed, run)`` inside the
worker, so the result does not depend on the number of processes.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any


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
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for s in pool.map(worker, todo, chunksize=chunk):
                out.append(s)
                if progress:
                    progress(1)
    return sorted(out, key=lambda s: s.run)
