"""A sweep's grid: ``KEY=V1,V2,...`` over any config setting of an experiment, the cells of
their product, each cell's config built and validated through the experiment's contract.

A key is a config field (``sigma_alpha_arcmin``) or its command-line name (``sigma-alpha``),
or ``scenario``; values are parsed the way the option parses them (``1920x1080`` for an
image size), else by the field's type (numbers, booleans as true/false/on/off/1/0, text).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Iterable, Mapping
from typing import Any

from workbench.core.experiment import Experiment
from workbench.errors import WorkbenchError
from workbench.loading import split_list

FIXED = ("seed", "runs", "estimators")
"""Settings a sweep owns (it seeds and counts runs itself) and a grid cannot take."""


def _field_types(exp: Experiment) -> dict[str, Any]:
    """Each config field's default (or scenario base), which gives the type to parse values as."""
    out = {}
    for f in dataclasses.fields(exp.config_type):
        default = f.metadata.get("base", f.default)
        out[f.name] = None if default is dataclasses.MISSING else default
    return out


def resolve_key(exp: Experiment, key: str) -> str:
    """A config field's name from a key given as the field or as its option's flag."""
    key = key.strip()
    flags = {}
    for opt in exp.settable:
        for flag in opt.flags:
            for name in flag.split("/"):
                flags[name.lstrip("-")] = opt.fields[0] if len(opt.fields) == 1 else opt.field
    fields = _field_types(exp)
    name = key if key in fields or key == "scenario" else flags.get(key, key.replace("-", "_"))
    if name in FIXED:
        raise WorkbenchError(f"--grid {key}: a sweep sets {name} itself (use --{name})")
    if name not in fields and name != "scenario" and name not in _multi(exp):
        raise WorkbenchError(f"--grid {key}: {exp.name} has no setting {key!r}; see `workbench {exp.name} --help`")
    return name


def parse_value(exp: Experiment, field: str, text: str) -> Any:
    """One grid value of ``field`` from its text."""
    text = text.strip()
    if field == "scenario":
        if text not in exp.scenarios:
            raise WorkbenchError(f"--grid scenario={text}: choose from {', '.join(exp.scenarios)}")
        return text
    for opt in exp.settable:
        if field in (opt.field, *opt.fields) and opt.parse is not None:
            return opt.value(text)
    name = _multi(exp).get(field, (field,))[0]
    default = _field_types(exp).get(name, 0)
    if default is None:  # no default to type it by (None: "the data's own"): the field's annotation
        from workbench.config.files import field_type

        kind = field_type(exp, name)
        default = {float: 0.0, int: 0, bool: False}.get(kind, default)
    try:
        if isinstance(default, bool):
            low = text.lower()
            if low not in ("true", "false", "on", "off", "1", "0", "yes", "no"):
                raise ValueError(f"not a boolean: {text!r}")
            return low in ("true", "on", "1", "yes")
        if isinstance(default, int):
            return int(text)
        if isinstance(default, float) or default is None and _looks_numeric(text):
            return float(text)
        if isinstance(default, tuple) and not default:  # a list of names (add_metrics): comma-separated
            return split_list(text)
        if isinstance(default, tuple):
            raise ValueError("a tuple setting cannot be swept here")
        return text
    except ValueError as exc:
        raise WorkbenchError(f"--grid {field}={text}: {exc}") from None


def _looks_numeric(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def parse(exp: Experiment, specs: Iterable[str]) -> dict[str, tuple]:
    """``["lam=0.95,1", "window=60,120"]`` -> ``{"lam": (0.95, 1.0), "window": (60, 120)}``."""
    grid: dict[str, tuple] = {}
    for spec in specs:
        key, eq, values = str(spec).partition("=")
        if not eq or not key.strip() or not values.strip():
            raise WorkbenchError(f"--grid {spec!r} must look like KEY=V1,V2,...")
        field = resolve_key(exp, key)
        if field in grid:
            raise WorkbenchError(f"--grid {key} is given twice")
        vals = tuple(parse_value(exp, field, v) for v in split_list(values))
        if len(set(map(repr, vals))) != len(vals):
            raise WorkbenchError(f"--grid {key} repeats a value")
        grid[field] = vals
    return grid


def settings(exp: Experiment, items: Iterable[str]) -> dict[str, Any]:
    """``--set KEY=VALUE`` items (a sweep's or a study's settings for every cell or trial) as config
    overrides, each parsed as a grid value."""
    out: dict[str, Any] = {}
    for item in items:
        key, eq, value = str(item).partition("=")
        if not eq:
            raise WorkbenchError(f"--set {item!r} must look like KEY=VALUE")
        name = resolve_key(exp, key)
        out.update(expand(exp, {name: parse_value(exp, name, value)}))
    return out


def cells(grid: Mapping[str, tuple]) -> list[dict[str, Any]]:
    """The product of the grid's values, the first key slowest; one empty cell for no grid."""
    keys = list(grid)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*(grid[k] for k in keys))]


def _multi(exp: Experiment) -> dict[str, tuple[str, ...]]:
    """Options that set several fields at once (sea's ``order``: both AR orders)."""
    return {opt.field: opt.fields for opt in exp.settable if len(opt.fields) > 1}


def expand(exp: Experiment, cell: Mapping[str, Any]) -> dict[str, Any]:
    """A cell's settings as config overrides (an option of several fields sets each)."""
    multi = _multi(exp)
    out: dict[str, Any] = {}
    for key, value in cell.items():
        out.update({f: value for f in multi.get(key, (key,))})
    return out
