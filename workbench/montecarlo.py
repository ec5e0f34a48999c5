"""Monte Carlo runs over processes, shared by every experiment.

Each experiment supplies a picklable ``worker((cfg, run)) -> summary`` (a module-level
function) whose summary has a ``run`` attribute; run 0 may be given already computed (the
recorded run, with its trace). Runs are independent and seeded by ``(seed, run)`` inside the
worker, so the result does not depend on the number of processes.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any


def run_all(worker: Callable[[tuple[Any, int]], Any], cfg: Any, runs: int, first: Any = None,
            jobs: int | None = None, progress: Callable[[int], None] | None = None, chunksize: int = 1) -> list:
    """Summaries of runs ``0 .. runs-1``, sorted by run; ``first`` is run 0's summary if given."""
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
            out.append(worker((cfg, r)))
            if progress:
                progress(1)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for s in pool.map(worker, [(cfg, r) for r in todo], chunksize=chunksize):
                out.append(s)
                if progress:
                    progress(1)
    return sorted(out, key=lambda s: s.run)


def timed(runners: dict[str, Callable[[], Any]], names: tuple[str, ...] | list[str]) -> dict[str, Any]:
    """Run the named estimators in order on the same data; each result gets ``.seconds``."""
    out = {}
    for name in names:
        t0 = time.perf_counter()
        est = runners[name]()
        est.seconds = time.perf_counter() - t0
        out[name] = est
    return out
