"""The estimator side of the contract: what an estimator is, how every estimator runs on one
dataset, the checks its estimate must pass, and how a selection names one (built-in, installed
plugin, ``module:function`` / ``file.py:function`` spec, Python function).

This layer knows nothing of experiments beyond the small face an experiment shows it (a
``name``, its built-in table ``estimators`` and ``default_estimators``): the experiment side
(:mod:`.contract`) stands on it, never the other way round.

An estimator is a function ``(data, cfg) -> Estimate`` of the experiment's public dataset and
estimate types (``(data, cfg, ctx)`` where it wants the :class:`RunContext`). A selection
(``--estimators``, ``workbench.run(estimators=...)``, a sweep) is

* a built-in's name (the experiment's table), or ``+name`` first: the defaults and these;
* an installed plugin's name: an entry point of the group ``workbench.estimators`` named
  ``<experiment>.<estimator>`` (``sea.fixed-lag``), pointing at a function or an :class:`Estimator`;
* a spec ``module:function`` or ``path/to/file.py:function``, optionally named ``lagged=mypkg.filters:smoother``;
* a Python function (from the API); :func:`estimator` attaches its description, colour, whether
  it is causal and gives covariances.
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import os
import re
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from workbench import loading
from workbench.core.timeout import EstimatorTimedOut, call_with_timeout
from workbench.errors import WorkbenchError

Color = tuple[int, int, int]
GROUP = "workbench.estimators"
NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
# colours for plugins: saturated, apart from every built-in's (oranges, greens, cyans, reds,
# violets, pinks, greys), from the truth's white and the line of sight's pale yellow (a yellow was
# found too near the paper's orange in a browser review, a sky blue is too near the cyan), and readable on the
# maps' dark and the plots' light backgrounds
PLUGIN_COLORS: tuple[Color, ...] = ((0, 100, 255), (150, 220, 0), (255, 0, 255), (0, 150, 110), (120, 60, 200))


class EstimateError(ValueError):
    """An estimate that breaks its type's contract (shape, NaNs, a covariance not PSD)."""


@dataclass
class RunContext:
    """What a built-in (or a plugin that asks for it) gets beside the data and the config.

    ``record``: this run is the recorded one (compute what only the recording draws: traces,
    covariances at every step). ``shared(key, make)``: a product several estimators use (a
    factor set, a search), made once per run; each estimator using it is charged its time.
    """

    run: int = 0
    record: bool = False
    threads: int = 1
    cache: dict = field(default_factory=dict)
    _fresh: float = 0.0
    _used: set = field(default_factory=set)

    def shared(self, key: str, make: Callable[[], Any]) -> Any:
        if key not in self.cache:
            t0 = time.perf_counter()
            value = make()
            cost = time.perf_counter() - t0
            self.cache[key] = (value, cost)
            self._fresh += cost
        self._used.add(key)
        return self.cache[key][0]

    def get(self, key: str, default: Any = None) -> Any:
        """A shared product if some estimator made it (for evaluation and the recording)."""
        return self.cache[key][0] if key in self.cache else default

    def products(self) -> dict[str, Any]:
        """Every shared product made in this run, by key."""
        return {k: v for k, (v, _) in self.cache.items()}


@dataclass(eq=False)
class Estimator:
    """One row of an estimator table.

    ``run`` is ``(data, cfg)`` or, if it takes a third argument, ``(data, cfg, ctx)``; a
    ``"module:function"`` string is imported when first run (a built-in's row costs no
    import). ``ref`` finds it again in another process (its name, or its ``module:function`` /
    ``file.py:function`` spec); ``source`` says where it came from (``built-in``, an entry
    point, a spec, a Python object)."""

    name: str
    run: Callable[..., Any]
    color: Color
    description: str
    causal: bool
    covariances: bool
    experiment: str = ""
    source: str = "built-in"
    ref: str | None = None
    indefinite: str = ""  # why its covariance may be indefinite (then not checked to be PSD): a known flaw
    lag: float | None = None  # seconds of data after step k its estimate of k uses (None: 0 if causal, else all)

    @property
    def delay(self) -> float:
        """The seconds of data after a step its estimate of that step uses: 0 for a filter, ``inf``
        for a smoother of the whole run, the lag of a fixed-lag smoother. Which Cramér-Rao bound
        it is held to follows: filtering, smoothing, or the bound of that lag."""
        if self.lag is not None:
            return float(self.lag)
        return 0.0 if self.causal else float("inf")

    @property
    def builtin(self) -> bool:
        return self.source == "built-in"

    @property
    def spec(self) -> str:
        """What selects it again (in a config, a sweep's task): its name, or ``name=ref``."""
        return self.name if self.ref in (None, self.name) else f"{self.name}={self.ref}"

    def function(self) -> Callable[..., Any]:
        """The runner; a ``"module:function"`` string is imported when first needed."""
        if isinstance(self.run, str):
            self.run = loading.load(self.run)
        return self.run

    @property
    def takes_context(self) -> bool:
        try:
            return len(inspect.signature(self.function()).parameters) >= 3
        except (TypeError, ValueError):
            return False

    def __call__(self, data: Any, cfg: Any, ctx: RunContext) -> Any:
        fn = self.function()
        return fn(data, cfg, ctx) if self.takes_context else fn(data, cfg)

    def __reduce__(self):
        # a Python object without a ref goes by reference; one with a ref is sent to a worker
        # process as how to find it, not as its code (a file-loaded plugin or an entry point
        # loads again there): the registry, which can find its experiment, registers that
        # reduction (copyreg, :mod:`workbench.core.registry`), which pickle takes before this one
        return Estimator, (self.name, self.run, self.color, self.description, self.causal, self.covariances,
                           self.experiment, self.source, self.ref, self.indefinite, self.lag)

    def describe(self) -> dict:
        out = {"description": self.description, "causal": self.causal, "covariances": self.covariances,
               "source": self.source, "color": list(self.color)}
        if self.indefinite:
            out["indefinite_covariance"] = self.indefinite
        if self.lag is not None:
            out["lag_seconds"] = self.lag
        return out


def table(experiment: str, *rows: Estimator) -> dict[str, Estimator]:
    """An experiment's built-in estimator table, name -> row, in the order given."""
    return {e.name: dataclasses.replace(e, experiment=experiment, ref=e.name) for e in rows}


def estimate_all(estimators: Iterable[Estimator], data: Any, cfg: Any, ctx: RunContext,
                 check: Callable[[Any, Any, Any, Estimator], Any]) -> tuple[dict[str, Any], dict[str, str]]:
    """Every estimator on the same data, in order, each timed and checked.

    Returns the estimates by name and the failures (name -> one line): an estimator that
    raises, whose estimate fails ``check``, or that takes longer than ``cfg.estimator_timeout``
    seconds (:func:`call_with_timeout`; 0 or absent: no limit) is left out, the others go on. One
    that timed out is not called again on the same config in this process (:data:`_TIMED_OUT`):
    its later runs fail at once. Each estimate's ``seconds`` is its own time plus that of the
    shared products it used (:meth:`RunContext.shared`). ``WORKBENCH_DEBUG=1`` re-raises instead.
    """
    out: dict[str, Any] = {}
    failures: dict[str, str] = {}
    limit = float(getattr(cfg, "estimator_timeout", 0.0) or 0.0)
    this = _config_key(cfg) if limit else None
    for est in estimators:
        key = (est.spec, this)
        if limit and key in _TIMED_OUT:
            failures[est.name] = f"timed out in an earlier run (after {_TIMED_OUT[key]:g} s); not run again"
            continue
        own_ctx = dataclasses.replace(ctx, _fresh=0.0, _used=set())  # its accounts; the shared products are one
        t0 = time.perf_counter()
        try:
            result = call_with_timeout(est, (data, cfg, own_ctx), limit, est.name)
            result = check(result, data, cfg, est)
        except KeyboardInterrupt:
            raise
        except EstimatorTimedOut as exc:
            if os.environ.get("WORKBENCH_DEBUG"):
                raise
            _TIMED_OUT[key] = limit
            ctx.cache = dict(ctx.cache)  # what the abandoned call may still add goes to a dict no one reads
            failures[est.name] = one_line(exc)
            continue
        except Exception as exc:
            if os.environ.get("WORKBENCH_DEBUG"):
                raise
            failures[est.name] = one_line(exc)
            continue
        own = time.perf_counter() - t0 - own_ctx._fresh
        result.seconds = own + sum(ctx.cache[k][1] for k in own_ctx._used)
        out[est.name] = result
    return out, failures


_TIMED_OUT: dict[tuple, float] = {}
"""(estimator spec, config key) -> the limit it went past, in this process: not called again.
A Monte Carlo worker forked after run 0 inherits it, so it does not wait again either."""


def _config_key(cfg: Any) -> Any:
    """What tells one config from another for :data:`_TIMED_OUT`: every field but ``runs`` (a
    sweep's tasks of one cell differ only there), or the object itself where it is no dataclass."""
    if not dataclasses.is_dataclass(cfg):
        return id(cfg)
    return tuple((f.name, repr(getattr(cfg, f.name))) for f in dataclasses.fields(cfg) if f.name != "runs")


def one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    first = text[0] if text else ""
    return f"{type(exc).__name__}: {first}" if not isinstance(exc, (EstimateError, WorkbenchError)) else first


# --- checks an estimate must pass (shared by the experiments' ``check``) ------------------------------

def as_array(value: Any, what: str, shape: tuple[int | None, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape`` (None: any length), else :class:`EstimateError`."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise EstimateError(f"{what} is not an array of numbers") from None
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape, strict=True)):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise EstimateError(f"{what} has shape {a.shape}, expected {want}")
    if np.isinf(a).any():
        raise EstimateError(f"{what} has infinite values")
    return a


def whole_rows(a: np.ndarray, what: str, axes: int = 1, allow_empty: bool = True) -> np.ndarray:
    """Each row (the last ``axes`` axes) is all finite or all NaN ("no estimate at this step");
    a partly-NaN row, or NaN everywhere (unless ``allow_empty``), is an :class:`EstimateError`.
    Returns the rows' finite mask."""
    inner = tuple(range(a.ndim - axes, a.ndim))
    nan = np.isnan(a)
    some, every = nan.any(axis=inner), nan.all(axis=inner)
    if (some & ~every).any():
        k = int(np.flatnonzero(some & ~every)[0])
        raise EstimateError(f"{what} is partly NaN at row {k} (a row is all numbers or all NaN)")
    if not allow_empty and every.all():
        raise EstimateError(f"{what} is NaN everywhere")
    return ~every


def psd(cov: np.ndarray, what: str, rows: np.ndarray | None = None, estimator: Estimator | None = None) -> None:
    """Symmetric positive semi-definite (to round-off) wherever finite; rows that must be
    finite (``rows`` True) are checked to be. An estimator whose table row says why its
    covariance may be indefinite (``indefinite``, a known flaw such as the omni paper's
    augmentation) is not held to PSD."""
    cov = np.asarray(cov, float)
    finite = np.isfinite(cov).all(axis=(-1, -2))
    if rows is not None and (rows & ~finite).any():
        k = int(np.flatnonzero(rows & ~finite)[0])
        raise EstimateError(f"{what} is not finite at row {k}, where the estimate is")
    if estimator is not None and estimator.indefinite:
        return
    c = cov[finite]
    if not len(c):
        return
    scale = np.maximum(np.abs(c).max(axis=(-1, -2)), 1e-300)
    asym = np.abs(c - np.swapaxes(c, -1, -2)).max(axis=(-1, -2)) / scale
    if (asym > 1e-6).any():
        k = int(np.flatnonzero(finite)[np.argmax(asym > 1e-6)])
        raise EstimateError(f"{what} is not symmetric at row {k}")
    sym = (c + np.swapaxes(c, -1, -2)) / 2
    low = np.zeros(c.shape[:-2])
    doubt = ~_leading_minors_positive(sym)   # positive definite by Sylvester's criterion: no eigenvalues needed
    if doubt.any():
        low[doubt] = np.linalg.eigvalsh(sym[doubt]).min(axis=-1)
    if (low < -1e-9 * scale).any():
        k = int(np.flatnonzero(finite)[np.argmax(low < -1e-9 * scale)])
        raise EstimateError(f"{what} is not positive semi-definite at row {k} (eigenvalue {low.min():.3g})")


def _leading_minors_positive(c: np.ndarray) -> np.ndarray:
    """Per symmetric matrix of ``c (..., n, n)``, whether its leading principal minors are all
    positive (Sylvester's criterion: positive definite), in closed form for ``n <= 3`` (the poses'
    and the landmarks' covariances, tens of thousands per estimate); False (ask the eigenvalues)
    for larger ones."""
    n = c.shape[-1]
    if n > 3:
        return np.zeros(c.shape[:-2], bool)
    with np.errstate(over="ignore", invalid="ignore"):   # a huge one's minor overflows: inf > 0, NaN doubtful
        ok = c[..., 0, 0] > 0
        if n >= 2:
            ok &= c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] * c[..., 1, 0] > 0
        if n == 3:
            det = (c[..., 0, 0] * (c[..., 1, 1] * c[..., 2, 2] - c[..., 1, 2] * c[..., 2, 1])
                   - c[..., 0, 1] * (c[..., 1, 0] * c[..., 2, 2] - c[..., 1, 2] * c[..., 2, 0])
                   + c[..., 0, 2] * (c[..., 1, 0] * c[..., 2, 1] - c[..., 1, 1] * c[..., 2, 0]))
            ok &= det > 0
    return ok


# --- naming an estimator: built-ins, installed plugins, specs, functions ---------------------------

def estimator(*, name: str | None = None, description: str | None = None, causal: bool = False,
              covariances: bool = False, color: Color | None = None, lag: float | None = None) -> Callable:
    """Decorate a plugin function with what the tables, metrics and recordings show of it;
    ``lag``: the seconds of data after a step its estimate of that step uses (a fixed-lag
    smoother's; by default 0 if ``causal``, else the whole run), which decides its Cramér-Rao bound."""

    def mark(fn: Callable) -> Callable:
        fn.__workbench__ = {"name": name, "description": description, "causal": causal,
                            "covariances": covariances, "color": color, "lag": lag}
        return fn

    return mark


def installed(experiment: str) -> dict:
    """The experiment's installed plugins by estimator name (entry points, not yet loaded)."""
    return loading.entry_points(GROUP, experiment + ".")


def resolve(exp: Any, selection: Iterable[Any] | str | None) -> list[Estimator]:
    """The selection of experiment ``exp`` as estimators, in order; one-line errors for anything unknown."""
    items: list[Any] = list(exp.default_estimators if selection is None
                            else loading.split_list(selection) if isinstance(selection, str) else selection)
    if items and isinstance(items[0], str) and items[0].startswith("+"):
        items = [*exp.default_estimators, items[0][1:], *items[1:]]
    out: list[Estimator] = []
    for item in items:
        est = one(exp, item)
        if est.name in {e.name for e in out}:
            raise WorkbenchError(f"estimator {est.name!r} is selected twice")
        taken = {e.color for e in out}
        if not est.builtin and est.color in taken:  # two plugins on one colour: the next free one
            free = [c for c in PLUGIN_COLORS if c not in taken]
            est = dataclasses.replace(est, color=free[0] if free else est.color)
        out.append(est)
    if not out:
        raise WorkbenchError("no estimator selected")
    return out


def plugin_color(name: str) -> Color:
    """A plugin's colour by its name (the same in every run, experiment and recording that has
    it, whatever else is selected): one of :data:`PLUGIN_COLORS`, chosen by a stable hash."""
    return PLUGIN_COLORS[hashlib.sha1(name.encode()).digest()[0] % len(PLUGIN_COLORS)]


def one(exp: Any, item: Any, color: Color | None = None) -> Estimator:
    """One item of a selection as an :class:`Estimator` of ``exp`` (:func:`workbench.loading.resolve`)."""
    plugins = installed(exp.name)

    def unknown(text: str) -> str:
        extra = ", ".join(plugins)
        return (f"unknown estimator {text!r} for {exp.name}; built-in: {', '.join(exp.estimators)}"
                + (f"; installed: {extra}" if extra else "") + "; or a module:function / file.py:function spec")

    found = loading.resolve(item, "estimator", Estimator, exp.estimators, plugins, unknown, NAME.pattern)
    name = found.name
    if found.how == "row":
        return item if item.experiment else dataclasses.replace(item, experiment=exp.name)
    if found.how == "function":
        return from_function(exp, item, None, loading.python_ref(item), "python", color)
    if found.how == "built-in":
        est = found.value
        return dataclasses.replace(est, name=name) if name and name != est.name else est
    if found.how == "installed":
        ep, obj = found.entry_point, found.value
        if isinstance(obj, Estimator):
            return dataclasses.replace(obj, name=name or obj.name, experiment=exp.name, source=f"entry point {ep.name}",
                                       ref=found.key)
        return from_function(exp, obj, name or found.key, found.key, f"entry point {ep.name} ({ep.value})", color)
    return from_function(exp, found.value, name, loading.spec_ref(found.key), found.key, color)


def from_function(exp: Any, fn: Any, name: str | None, ref: str | None, source: str,
                  color: Color | None = None) -> Estimator:
    """An :class:`Estimator` from a plugin function and what :func:`estimator` attached to it."""
    if not callable(fn):
        raise WorkbenchError(f"estimator {source} is not a function")
    meta = getattr(fn, "__workbench__", {})
    name = name or meta.get("name") or getattr(fn, "__name__", None) or "plugin"
    if not NAME.fullmatch(name):
        raise WorkbenchError(f"estimator name {name!r}: use letters, digits and . _ - only")
    doc = (inspect.getdoc(fn) or "").strip().splitlines()
    description = meta.get("description") or (doc[0] if doc else f"{name} (a plugin)")
    rgb = tuple(meta.get("color") or color or plugin_color(name))
    lag = meta.get("lag")
    return Estimator(name, fn, rgb, description, bool(meta.get("causal", False)),
                     bool(meta.get("covariances", False)), exp.name, source, ref,
                     lag=float(lag) if lag is not None else None)
