"""The checks every experiment's config passes after its own ``validate()``: one layer, so no
option of any experiment reaches the code as a non-finite number, an absurd magnitude, or a
size the machine cannot hold.

* every number finite (``inf`` and ``nan`` are never a setting), within :data:`MAX_MAGNITUDE`
  in its own units (UTM coordinates are ~1e7 m; 1e300 is a typo), and zero or at least
  :data:`MIN_MAGNITUDE` (a denormal time step overflows the step count);
* whole numbers within :data:`MAX_INT`; ``--seed`` within 64 bits (the recording stores it so),
  ``--runs`` at most :data:`MAX_RUNS`; ``--estimator-timeout`` a number of seconds, at least 0;
* the memory a run will need (``cfg.memory_bytes()``, each experiment's estimate from what
  sizes its arrays: steps, keyframes, DEM cells, pixels, and the summaries of every run the
  parent holds) at most :func:`memory_limit`, refused before any work.

Errors name the flag as the user types it.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from typing import Any

from workbench.errors import require

MAX_MAGNITUDE = 1e9
MIN_MAGNITUDE = 1e-100  # a number divided by it stays finite (5e-324 as a time step overflowed)
MAX_INT = 2**53
MAX_SEED = 2**63 - 1
MAX_RUNS = 1_000_000
MEMORY_SHARE = 0.5  # of the machine's physical memory


def memory_limit() -> int:
    """Bytes a run may plan to use: ``WORKBENCH_MEMORY_LIMIT`` (bytes) if set, else half the
    machine's physical memory."""
    given = os.environ.get("WORKBENCH_MEMORY_LIMIT")
    if given:
        return int(float(given))
    try:
        return int(MEMORY_SHARE * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # not POSIX: assume 8 GB
        return int(MEMORY_SHARE * 8 * 2**30)


def _numbers(value: Any) -> list:
    if isinstance(value, (tuple, list)):
        return [x for v in value for x in _numbers(v)]
    return [value]


def check_values(cfg: Any, flags: Mapping[str, str]) -> None:
    """Every number of ``cfg`` finite and of sane size; ``seed`` and ``runs`` in range."""
    for f in dataclasses.fields(cfg):
        flag = flags.get(f.name, "--" + f.name.replace("_", "-"))
        for x in _numbers(getattr(cfg, f.name)):
            if isinstance(x, bool) or x is None:
                continue
            if isinstance(x, float):
                require(math.isfinite(x), f"{flag} must be a finite number, got {x}")
                require(abs(x) <= MAX_MAGNITUDE, f"{flag} {x:g} is out of range (at most {MAX_MAGNITUDE:g} in size)")
                require(x == 0.0 or abs(x) >= MIN_MAGNITUDE,
                        f"{flag} {x:g} is too small to compute with (0, or at least {MIN_MAGNITUDE:g} in size)")
            elif isinstance(x, int) and f.name != "seed":
                require(abs(x) <= MAX_INT, f"{flag} {x} is out of range (at most 2**53 in size)")
    seed, runs = getattr(cfg, "seed", 0), getattr(cfg, "runs", 1)
    require(isinstance(seed, int) and 0 <= seed <= MAX_SEED, f"--seed must be in 0..2**63-1, got {seed}")
    require(isinstance(runs, int) and 1 <= runs <= MAX_RUNS, f"--runs must be in 1..{MAX_RUNS}, got {runs}")
    limit = getattr(cfg, "estimator_timeout", 0.0)
    require(isinstance(limit, (int, float)) and not isinstance(limit, bool) and limit >= 0,
            f"--estimator-timeout must be seconds, at least 0 (0: no limit), got {limit!r}")


def check_memory(cfg: Any) -> None:
    """Refuse a run whose estimated memory (``cfg.memory_bytes() -> (bytes, what sizes it)``)
    is over :func:`memory_limit`."""
    estimate = getattr(cfg, "memory_bytes", None)
    if estimate is None:
        return
    need, why = estimate()
    limit = memory_limit()
    require(need <= limit, f"this run would need about {_size(need)} of memory ({why}), over the limit of "
                           f"{_size(limit)} (half this machine's; WORKBENCH_MEMORY_LIMIT sets it)")


def check_jobs(jobs: int | None) -> None:
    """``--jobs``: at least 1, at most the machine's cores (more processes only add memory)."""
    if jobs is None:
        return
    cores = os.cpu_count() or 1
    require(1 <= jobs <= cores, f"--jobs must be in 1..{cores} (this machine's cores), got {jobs}")


def _size(n: float) -> str:
    for unit, scale in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n / 2**10:.0f} kB"
