"""Loading what a researcher names from outside the package, the same way for estimators,
metrics and experiments: a ``module:function`` spec (importable, the working folder included),
a ``path/to/file.py:function`` spec, or an installed package's entry point.

Below everything that loads plugins (:mod:`workbench.core.estimator`,
:mod:`workbench.metrics.base`, the registry): it imports nothing of the workbench but its
errors. Every failure is a one-line :class:`~workbench.errors.WorkbenchError` naming what was
asked for, never the plugin's traceback.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.metadata
import importlib.util
import os
import re
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from workbench.errors import WorkbenchError


def load(spec: str, what: str = "estimator") -> Any:
    """``module:function`` or ``path/to/file.py:function`` (dotted attributes allowed); ``what``
    names the kind of plugin in the errors."""
    target, _, attr = str(spec).rpartition(":")
    if not target or not attr:
        raise WorkbenchError(f"{what} spec {spec!r} must look like module:function or file.py:function")
    if is_file_spec(target):
        module = from_file(Path(target), what)
    else:
        if os.getcwd() not in sys.path:  # as `python -m` does: modules beside the user are found
            sys.path.append(os.getcwd())
        try:
            module = importlib.import_module(target)
        except Exception as exc:  # a plugin's import error of any kind is the user's to fix
            raise WorkbenchError(f"cannot import {what} module {target!r}: {type(exc).__name__}: "
                                 f"{first_line(exc)}") from None
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise WorkbenchError(f"{target} has no {attr!r}")
        obj = getattr(obj, part)
    return obj


def is_file_spec(target: str) -> bool:
    return target.endswith(".py") or "/" in target or os.sep in target


def from_file(path: Path, what: str = "estimator") -> Any:
    """A Python file as a module (once per path), its folder on the path for its siblings."""
    path = path.expanduser().resolve()
    if not path.is_file():
        raise WorkbenchError(f"{what} file not found: {path}")
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
        raise WorkbenchError(f"cannot load {what} file {path}: {type(exc).__name__}: {first_line(exc)}") from None
    return module


@functools.cache
def entry_points(group: str, prefix: str = "") -> dict[str, importlib.metadata.EntryPoint]:
    """The installed entry points of ``group`` whose names start with ``prefix`` (which is cut
    off the names), not yet loaded."""
    return {ep.name[len(prefix):]: ep for ep in importlib.metadata.entry_points(group=group)
            if ep.name.startswith(prefix)}


def load_entry_point(ep: importlib.metadata.EntryPoint, what: str) -> Any:
    """An entry point's object; ``what`` says which plugin in the one-line error."""
    try:
        return ep.load()
    except Exception as exc:
        dist = getattr(ep, "dist", None)
        hint = f" (from {dist.name})" if dist is not None else ""
        raise WorkbenchError(f"installed {what}{hint} cannot be loaded: {type(exc).__name__}: "
                             f"{first_line(exc)}") from None


def spec_ref(spec: str) -> str:
    """A spec with its file made absolute, so another process (or folder) finds it again."""
    target, _, attr = spec.rpartition(":")
    if is_file_spec(target):
        return f"{Path(target).expanduser().resolve()}:{attr}"
    return spec


def python_ref(fn: Any) -> str | None:
    """``module:qualname`` where another process can import it; None otherwise (then it goes
    by reference, which a forked worker resolves)."""
    mod, qual = getattr(fn, "__module__", None), getattr(fn, "__qualname__", "")
    if not mod or mod == "__main__" or "<" in qual or mod.startswith("workbench_plugin_"):
        return None
    return f"{mod}:{qual}"


def first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else ""


def split_list(text: str) -> tuple[str, ...]:
    """``"a, b,c"`` -> ``("a", "b", "c")``: a selection as the command line gives it."""
    return tuple(p.strip() for p in str(text).split(",") if p.strip())


NAME_PATTERN = r"[A-Za-z0-9_][A-Za-z0-9_.-]*"
"""A plugin's name: letters, digits and ``. _ -`` (what ``name=spec`` may call it)."""


@dataclass(frozen=True)
class Found:
    """What an item of a selection named, before it is made an estimator's or a metric's row.

    ``how``: ``"row"`` (already the row type), ``"function"`` (a Python function), ``"built-in"``
    (``value`` the experiment's own row), ``"installed"`` (``value`` the entry point's object,
    ``entry_point`` it), ``"spec"`` (``value`` the function a ``module:function`` or
    ``file.py:function`` spec loads). ``name``: the ``name=`` given, if any; ``key``: the item as
    named (the built-in's or installed name, or the spec)."""

    how: str
    value: Any
    key: str = ""
    name: str | None = None
    entry_point: importlib.metadata.EntryPoint | None = None


def resolve(item: Any, what: str, row_type: type, builtins: Mapping[str, Any],
            installed: Mapping[str, importlib.metadata.EntryPoint], unknown: Callable[[str], str],
            name_pattern: str = NAME_PATTERN) -> Found:
    """One item of a selection, the same way for estimators and metrics: a row, a Python
    function, or a string naming (optionally as ``name=...``) a built-in, an installed entry point
    or a ``module:function`` / ``file.py:function`` spec. ``unknown(item)`` words the one-line
    error for a string that names none of them; ``name_pattern`` what a ``name=`` may be."""
    if isinstance(item, row_type):
        return Found("row", item)
    if callable(item):
        return Found("function", item)
    if not isinstance(item, str):
        article = "an" if what[:1] in "aeiou" else "a"
        raise WorkbenchError(f"{article} {what} is a name, a module:function spec or a function, not {item!r}")
    text, name = item.strip(), None
    named = re.fullmatch(rf"({name_pattern})=(.+)", text)
    if named:
        name, text = named.group(1), named.group(2).strip()
    if text in builtins:
        return Found("built-in", builtins[text], text, name)
    if text in installed:
        ep = installed[text]
        return Found("installed", load_entry_point(ep, f"{what} {text!r}"), text, name, ep)
    if ":" in text:
        return Found("spec", load(text, what), text, name)
    raise WorkbenchError(unknown(text))
