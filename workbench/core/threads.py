"""One BLAS thread while the workbench estimates, as the command line has always run.

The estimators multiply small matrices, where OpenBLAS's extra threads only wait for work (they
spin), and the Monte Carlo runs already take every core. The ``workbench`` command sets
``OPENBLAS_NUM_THREADS=1`` before numpy loads (:mod:`workbench.cli`); a run started from Python
(a notebook, a sweep's Dask worker, a test) loaded numpy before the workbench could say so, and is
limited at run time instead (threadpoolctl, Pedregosa et al.: the same switch scikit-learn uses).
Measured on 2 cores with two pytest workers (``tests/test_bounds.py``, ``test_bootstrap.py`` and
``test_selftune.py``, twice each way): 187-189 s of CPU with numpy's default of a thread per core,
166-169 s with one."""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

P = ParamSpec("P")
R = TypeVar("R")

BLAS_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""A user who set one of these chose the threads; the workbench then leaves them as they are."""


def one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """A context in which BLAS runs on one thread (restored after), unless the user chose the
    number of threads in one of :data:`BLAS_VARIABLES`."""
    if any(v in os.environ for v in BLAS_VARIABLES):
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def on_one_blas_thread(fn: Callable[P, R]) -> Callable[P, R]:
    """``fn`` run inside :func:`one_blas_thread`."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with one_blas_thread():
            return fn(*args, **kwargs)

    return wrapper
