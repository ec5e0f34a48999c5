"""Estimators from outside the package, found the same way everywhere.

An estimator in a selection (``--estimators``, ``workbench.run(estimators=...)``, a sweep) is

* a built-in's name (the experiment's table), or ``+name`` first: the defaults and these;
* an installed plugin's name: an entry point of the group ``workbench.estimators`` named
  ``<experiment>.<estimator>`` (``sea.fixed-lag``), pointing at a function or an
  :class:`~workbench.experiments.contract.Estimator`;
* a spec ``module:function`` (importable, the working folder included) or
  ``path/to/file.py:function``, optionally named: ``lagged=mypkg.filters:smoother``;
* a Python function (from the API).

A plugin function is ``(data, cfg) -> Estimate`` (or ``(data, cfg, ctx)``); :func:`estimator`
attaches its description, colour and whether it is causal and gives covariances.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib
import importlib.metadata
import importlib.util
import inspect
import os
import re
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from workbench.errors import WorkbenchError
from workbench.experiments.contract import Color, Estimator, Experiment, split_list

GROUP = "workbench.estimators"
NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
# colours for plugins: saturated, apart from every built-in's (oranges, greens, cyans, reds,
# violets, pinks, greys), from the truth's white and the line of sight's pale yellow (a yellow was
# found too near the paper's orange in a browser review, a sky blue is too near the cyan), and readable on the
# maps' dark and the plots' light backgrounds
PLUGIN_COLORS: tuple[Color, ...] = ((0, 100, 255), (150, 220, 0), (255, 0, 255), (0, 150, 110), (120, 60, 200))


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


@functools.cache
def installed(experiment: str) -> dict[str, importlib.metadata.EntryPoint]:
    """The experiment's installed plugins by estimator name (entry points, not yet loaded)."""
    prefix = experiment + "."
    return {ep.name[len(prefix):]: ep for ep in importlib.metadata.entry_points(group=GROUP)
            if ep.name.startswith(prefix)}


def resolve(exp: Experiment, selection: Iterable[Any] | str | None) -> list[Estimator]:
    """The selection as estimators, in order; one-line errors for anything unknown."""
    items: list[Any] = list(exp.default_estimators if selection is None
                            else split_list(selection) if isinstance(selection, str) else selection)
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


def one(exp: Experiment, item: Any, color: Color | None = None) -> Estimator:
    """One item of a selection as an :class:`Estimator` of ``exp``."""
    if isinstance(item, Estimator):
        return item if item.experiment else dataclasses.replace(item, experiment=exp.name)
    if callable(item):
        return from_function(exp, item, None, _python_ref(item), "python", color)
    if not isinstance(item, str):
        raise WorkbenchError(f"an estimator is a name, a module:function spec or a function, not {item!r}")
    name = None
    m = re.fullmatch(rf"({NAME.pattern})=(.+)", item.strip())
    if m:
        name, item = m.group(1), m.group(2)
    item = item.strip()
    if item in exp.estimators:
        est = exp.estimators[item]
        return dataclasses.replace(est, name=name) if name and name != est.name else est
    if item in installed(exp.name):
        ep = installed(exp.name)[item]
        obj = _load_entry_point(exp, item, ep)
        if isinstance(obj, Estimator):
            return dataclasses.replace(obj, name=name or obj.name, experiment=exp.name, source=f"entry point {ep.name}",
                                       ref=item)
        return from_function(exp, obj, name or item, item, f"entry point {ep.name} ({ep.value})", color)
    if ":" in item:
        fn = load(item)
        return from_function(exp, fn, name, _spec_ref(item), item, color)
    known = ", ".join(exp.estimators)
    extra = ", ".join(installed(exp.name))
    raise WorkbenchError(f"unknown estimator {item!r} for {exp.name}; built-in: {known}"
                         + (f"; installed: {extra}" if extra else "")
                         + "; or a module:function / file.py:function spec")


def from_function(exp: Experiment, fn: Any, name: str | None, ref: str | None, source: str,
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


def load(spec: str) -> Callable:
    """``module:function`` or ``path/to/file.py:function`` (dotted attributes allowed)."""
    target, _, attr = spec.rpartition(":")
    if not target or not attr:
        raise WorkbenchError(f"estimator spec {spec!r} must look like module:function or file.py:function")
    if target.endswith(".py") or "/" in target or os.sep in target:
        module = _from_file(Path(target))
    else:
        if os.getcwd() not in sys.path:  # as `python -m` does: modules beside the user are found
            sys.path.append(os.getcwd())
        try:
            module = importlib.import_module(target)
        except Exception as exc:  # a plugin's import error of any kind is the user's to fix
            raise WorkbenchError(f"cannot import estimator module {target!r}: {type(exc).__name__}: "
                                 f"{_first(exc)}") from None
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise WorkbenchError(f"{target} has no {attr!r}")
        obj = getattr(obj, part)
    return obj


def _from_file(path: Path) -> Any:
    path = path.expanduser().resolve()
    if not path.is_file():
        raise WorkbenchError(f"estimator file not found: {path}")
    modname = "workbench_plugin_" + path.stem.replace("-", "_") + "_" + \
        hashlib.sha1(str(path).encode()).hexdigest()[:8]
    if modname in sys.modules:
        return sys.modules[modname]
    spec = importlib.util.spec_from_file_location(modname, path)
    if spec is None or spec.loader is None:
        raise WorkbenchError(f"cannot load {path} as Python")
    module = importlib.util.module_from_spec(spec)
    sys.modules[modname] = module
    if str(path.parent) not in sys.path:  # its sibling modules import as they would under `python file.py`
        sys.path.append(str(path.parent))
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        del sys.modules[modname]
        raise WorkbenchError(f"cannot load estimator file {path}: {type(exc).__name__}: {_first(exc)}") from None
    return module


def _load_entry_point(exp: Experiment, name: str, ep: importlib.metadata.EntryPoint) -> Any:
    try:
        return ep.load()
    except Exception as exc:
        dist = getattr(ep, "dist", None)
        hint = f" (from {dist.name})" if dist is not None else ""
        raise WorkbenchError(f"installed estimator {name!r} for {exp.name}{hint} cannot be loaded: "
                             f"{type(exc).__name__}: {_first(exc)}") from None


def _spec_ref(spec: str) -> str:
    """A spec with its file made absolute, so another process (or folder) finds it again."""
    target, _, attr = spec.rpartition(":")
    if target.endswith(".py") or "/" in target or os.sep in target:
        return f"{Path(target).expanduser().resolve()}:{attr}"
    return spec


def _python_ref(fn: Any) -> str | None:
    """``module:qualname`` where another process can import it; None otherwise (then it goes
    by reference, which a forked worker resolves)."""
    mod, qual = getattr(fn, "__module__", None), getattr(fn, "__qualname__", "")
    if not mod or mod == "__main__" or "<" in qual or mod.startswith("workbench_plugin_"):
        return None
    return f"{mod}:{qual}"


def _first(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else ""


@functools.lru_cache(maxsize=256)
def find(experiment: str, ref: str, name: str, color: Color | None = None) -> Estimator:
    """An estimator found again from its ref (in a worker process): unpickling goes here."""
    from workbench import experiments

    est = one(experiments.get(experiment), ref)
    if est.name != name or (color is not None and est.color != tuple(color)):
        est = dataclasses.replace(est, name=name, color=tuple(color) if color is not None else est.color)
    return est
