"""The objective ``--tune-noise`` searches (:mod:`.selftune`): a filter's per-measurement negative
log-likelihood terms on a log (:func:`terms`), and their charged NLL over a part of the log as a
function of the noise's log-values, each filter run cached and counted (:class:`_Objective`), with
the runs a search needs all at once shared by forked processes (:meth:`_Objective.prefetch`)."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from workbench.core.montecarlo import worker_init
from workbench.errors import WorkbenchError

JOBS = 2   # processes the independent filter runs (the Hessian's, the roughness's) share


@dataclasses.dataclass
class Terms:
    """A filter's per-measurement NLL terms on a log: each measurement's time, its term (NaN where
    it was left out or has none) and whether the filter kept it."""

    t: np.ndarray
    nll: np.ndarray
    used: np.ndarray
    held: Any = None   # a context manager in which the filter makes these rows again (its package's ``hold_rows``)

    def charged(self, part: tuple[float, float] | None = None) -> float:
        """The NLL of the measurements in the time span ``part`` (``(after, up to)``; all: None),
        each left out charged as the least likely one kept in the span; inf where none is."""
        mask = self.within(part)
        kept = self.nll[mask & self.used & np.isfinite(self.nll)]
        if kept.size == 0:
            return math.inf
        return float(kept.sum() + kept.max() * np.count_nonzero(mask & ~(self.used & np.isfinite(self.nll))))

    def within(self, part: tuple[float, float] | None) -> np.ndarray:
        return np.ones(len(self.t), bool) if part is None else (self.t > part[0]) & (self.t <= part[1])

    def count(self, part: tuple[float, float] | None = None) -> int:
        return int(np.count_nonzero(self.within(part)))


def terms(exp: Any, data: Any, cfg: Any, filt: str, values: dict[str, float], held: Any = None) -> Terms | None:
    """The filter's terms on ``data`` told ``values`` (config fields without ``assume_``), its rows
    those ``held`` makes where given (a :attr:`Terms.held`); None if it failed."""
    told = dataclasses.replace(cfg, **{f"assume_{k}": float(v) for k, v in values.items()})
    with held if held is not None else contextlib.nullcontext():
        estimates, failed = exp.estimate(data, told, [filt])
    if filt in failed:
        return None
    innov = getattr(estimates[filt], "innovations", None)
    if innov is None:
        raise WorkbenchError(f"--tune-noise: {filt} reports no innovations on this data")
    hold = getattr(exp.parts, "hold_rows", None)
    rows = held if held is not None else hold(estimates[filt]) if hold is not None else None
    if innov.outlier:   # a contaminated model: every measurement with an innovation is its term
        nll = innov.mixture_nll()
        return Terms(innov.t, nll, np.isfinite(nll), rows)
    return Terms(innov.t, innov.nll(), innov.used & innov.valid, rows)


class _Objective:
    """The charged NLL of a part of the measurements as a function of the log-values of ``names``,
    each filter run cached and counted.

    A filter's rows can change with the noise it is told: a SLAM filter initialises a landmark
    sooner or later, and the bearings it spends on that have no innovation. A sum over a changing
    set is not the likelihood of the same data (more rows of a likely measurement lower it for that
    alone), so the part's NLL is its charged mean per row times the part's rows at the start
    values (``ref``; from the refinement on, at the first part's answer, where the data's rows are
    nearer what the noise they carry makes): the same data's count at every point of a search, the
    sum itself where the rows do not change (a Kalman filter's).

    Where the experiment can hold a filter's rows (its package's ``hold_rows``: omni's EKF, its
    landmarks initialised where one run initialised them, :class:`~workbench.experiments.omni.
    algorithms.ekf.HeldInit`), :meth:`hold_at` holds those the filter makes at a point for every run
    after: the likelihood is then that of the same rows at every noise, smooth, with no jumps for a
    search or a curvature to misread."""

    def __init__(self, exp: Any, data: Any, cfg: Any, filt: str, names: list[str]):
        self.exp, self.data, self.cfg, self.filt, self.names = exp, data, cfg, filt, names
        self.cache: dict[tuple, Terms | None] = {}
        self.ref: Terms | None = None
        self.held: Any = None
        self.made = 0   # filter runs made, over every hold

    def run(self, x: np.ndarray) -> Terms | None:
        key = tuple(np.round(np.asarray(x, float), 12))
        if key not in self.cache:
            self.made += 1
            self.cache[key] = terms(self.exp, self.data, self.cfg, self.filt,
                                    dict(zip(self.names, np.exp(key), strict=True)), self.held)
        return self.cache[key]

    @property
    def holds(self) -> bool:
        """Whether the experiment holds a filter's rows (:meth:`hold_at`)."""
        return getattr(self.exp.parts, "hold_rows", None) is not None

    def hold_at(self, x: np.ndarray) -> Terms | None:
        """The filter's run at ``x`` with the rows it makes there, and those rows held for every
        run from now on (cached: made again with its own rows held it is the same run; the cache of
        other rows emptied, kept where the rows are those held already). Where the experiment holds
        no rows, :meth:`run`."""
        if not self.holds:
            return self.run(x)
        key = tuple(np.round(np.asarray(x, float), 12))
        got = terms(self.exp, self.data, self.cfg, self.filt, dict(zip(self.names, np.exp(key), strict=True)))
        self.made += 1
        rows = None if got is None else got.held
        if rows is None or rows != self.held:
            self.held, self.cache = rows, {}
        self.cache[key] = got
        return got

    def prefetch(self, points: list[np.ndarray]) -> None:
        """The filter runs at ``points`` not yet cached, at once (:meth:`map`; each run is
        independent: the cache then holds what :meth:`run` would have computed one by one)."""
        keys = list(dict.fromkeys(tuple(np.round(np.asarray(x, float), 12)) for x in points))
        self.map(_run_key, [k for k in keys if k not in self.cache])

    def map(self, fn: Callable[[_Objective, Any], Any], args: list) -> list:
        """``fn(self, arg)`` for each of ``args`` (``fn`` a module-level function), over :data:`JOBS`
        forked processes where this machine has the cores (else here, one by one: the same answers,
        each call's own), the filter runs each made added to the cache."""
        jobs = min(JOBS, os.cpu_count() or 1, len(args))
        if (jobs < 2 or "fork" not in multiprocessing.get_all_start_methods()
                or multiprocessing.get_start_method(allow_none=True) not in (None, "fork")
                or multiprocessing.current_process().daemon):   # (a daemon, e.g. a Dask worker, has no children)
            return [fn(self, a) for a in args]
        global _FORKED
        _FORKED = self
        try:
            with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("fork"),
                                     initializer=worker_init) as pool:
                done = list(pool.map(_forked_call, [(fn, a) for a in args]))
        finally:
            _FORKED = None
        for _, runs in done:
            self.made += len(runs)
            for k, got in runs.items():
                self.cache.setdefault(k, got)
        return [out for out, _ in done]

    def value(self, x: np.ndarray, part: tuple[float, float] | None) -> float:
        got = self.run(x)
        if got is None or self.ref is None or not got.count(part):
            return math.inf
        return got.charged(part) / got.count(part) * self.ref.count(part)


_FORKED: _Objective | None = None   # the objective a forked worker of :meth:`_Objective.map` reads


def _forked_call(job: tuple) -> tuple[Any, dict]:
    fn, arg = job
    obj = _FORKED
    before = set(obj.cache)
    out = fn(obj, arg)
    return out, {k: v for k, v in obj.cache.items() if k not in before}


def _run_key(obj: _Objective, key: tuple) -> None:
    obj.run(np.asarray(key, float))
