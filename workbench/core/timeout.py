"""A time limit on one estimator call (``--estimator-timeout``): a researcher's filter stuck in a
loop costs them that estimator, not the run.

Python cannot kill a thread, and a process per call would pickle every dataset (and start a
process per estimator per run); so :func:`call_with_timeout` runs the call in a daemon thread and
waits for it at most the limit. Past it the thread is sent :class:`Abandoned`, which ends an
estimator looping in Python code at its next bytecode, and is left: one blocked in C code
(``time.sleep``, a native solver holding no Python frame) runs on, using its CPU and memory until it
returns or the process exits (a daemon thread never holds the exit), and whatever it returns is
discarded. What the caller sees is :class:`EstimatorTimedOut`, which it reports like an estimator
that raised (:func:`.estimator.estimate_all`). The normal path costs one thread start per call
(~0.1-0.4 ms, against ~0.7 s for the default sea run's six estimators).

Known limits: an estimator that catches ``BaseException`` (or a bare ``except:``) and loops on
is not stopped, only left; one holding the GIL in C code for ever holds the run too (no thread
can help there); an abandoned terrain search inside Numba's work-queue threading layer cannot
share it with the next estimator's search (the layer is not thread-safe).
"""

from __future__ import annotations

import ctypes
import threading
from collections.abc import Callable
from typing import Any

from workbench.errors import WorkbenchError


class EstimatorTimedOut(WorkbenchError):
    """An estimator took longer than ``--estimator-timeout``; it is left out like one that raised."""


class Abandoned(BaseException):
    """Raised inside the thread of an estimator past its time (:func:`call_with_timeout`): a
    ``BaseException``, so an estimator's own ``except Exception`` does not swallow it."""


def call_with_timeout(fn: Callable[..., Any], args: tuple, limit: float, name: str = "") -> Any:
    """``fn(*args)`` (the estimator ``name``), in a daemon thread waited for at most ``limit``
    seconds (0: no limit, called directly in this thread). Past it, :class:`Abandoned` is sent
    to the thread, which is left, and :class:`EstimatorTimedOut` raised here; what ``fn`` raises
    in time is raised here as it was (its traceback kept)."""
    if not limit:
        return fn(*args)
    box: dict[str, Any] = {}
    done = threading.Event()

    def work() -> None:
        try:
            box["value"] = fn(*args)
        except BaseException as exc:  # handed to the caller (or dropped, if abandoned)
            box["error"] = exc
        finally:
            done.set()

    thread = threading.Thread(target=work, name=f"workbench estimator {name}", daemon=True)
    thread.start()
    if not done.wait(limit):
        _interrupt(thread)
        raise EstimatorTimedOut(f"timed out after {limit:g} s (--estimator-timeout; 0 for no limit): stopped, "
                                "its result discarded")
    if "error" in box:
        error = box.pop("error")
        if isinstance(error, Abandoned):  # not ours: an estimator raising the class itself
            raise RuntimeError("raised workbench's Abandoned") from None
        raise error
    return box["value"]


def _interrupt(thread: Any) -> None:
    """Raise :class:`Abandoned` in ``thread`` (CPython's ``PyThreadState_SetAsyncExc``: delivered
    when the thread next runs Python bytecode; never, if it stays in C code)."""
    try:
        ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread.ident), ctypes.py_object(Abandoned))
    except (AttributeError, OSError, TypeError):  # not CPython: the thread is only left
        pass
