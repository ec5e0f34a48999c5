"""Config files: an experiment's settings in a TOML or JSON file (``--config FILE``).

The file is flat: ``key = value`` for any config field, the key as the field
(``sigma_alpha_arcmin``) or as its option (``sigma-alpha``), the same names the command line and
the sweeps take. The JSON a recording stores (``workbench info REC --config``) is such a file as
it is: its ``null`` values mean "the scenario's default". :meth:`Experiment.configure` puts the
file between the scenario's defaults (beneath) and the command line's overrides (on top).

Every key is checked against the config's field types: an unknown key, a value of the wrong type
(text for a number, a fraction for a count), a list of the wrong length: one line naming the file
and the key (:class:`~workbench.errors.WorkbenchError`). Ranges are the config's own ``validate``.
"""

from __future__ import annotations

import json
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from workbench.errors import WorkbenchError
from workbench.loading import split_list

SUFFIXES = (".toml", ".json")


def read(path: str | Path) -> dict[str, Any]:
    """The file's table of settings (TOML by its ``.toml`` suffix, JSON by ``.json``)."""
    path = Path(path).expanduser()
    if not str(path).strip() or not path.is_file():
        raise WorkbenchError(f"--config: no such file: {path}")
    if path.suffix.lower() not in SUFFIXES:
        raise WorkbenchError(f"--config {path}: a config file is .toml or .json, not {path.suffix or 'no suffix'!r}")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise WorkbenchError(f"--config {path}: cannot read it: {exc}") from None
    try:
        table = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise WorkbenchError(f"--config {path}: not TOML: {exc}") from None
    except json.JSONDecodeError as exc:
        raise WorkbenchError(f"--config {path}: not JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    if not isinstance(table, dict):
        raise WorkbenchError(f"--config {path}: the file must hold a table of key = value, "
                             f"not a {type(table).__name__}")
    return table


def settings(exp: Any, table: Mapping[str, Any], source: str = "--config") -> dict[str, Any]:
    """``table``'s values as config fields of ``exp``, each checked against its field's type.
    ``None`` (JSON ``null``) is left out: the scenario's default applies."""
    hints = typing.get_type_hints(exp.config_type)
    out: dict[str, Any] = {}
    for key, value in table.items():
        where = f"{source}: {key if str(key).isprintable() else repr(key)}"
        if isinstance(value, dict):
            raise WorkbenchError(f"{where}: a table; a config file is flat (key = value)")
        name, opt = resolve(exp, key)
        if name is None and opt is None:
            raise WorkbenchError(f"{where}: {exp.name} has no such setting; see `workbench {exp.name} --help`")
        if value is None:
            continue
        if opt is not None and opt.parse is not None and isinstance(value, str):
            parsed = opt.value(value)  # the option's own text form (an image size 1920x1080)
        else:
            parsed = _typed(hints[name or opt.fields[0]], value, where)
        for f in (opt.fields if opt is not None and name is None else (name,)):
            if f in out:
                raise WorkbenchError(f"{where}: {f} is set twice in the file")
            out[f] = parsed
    return out


def resolve(exp: Any, key: str) -> tuple[str | None, Any]:
    """A setting's config field from its key (the field's name, or its option's without the
    dashes), and the option that sets it (None where none does); ``(None, opt)`` for an option
    of several fields (sea's ``order``), ``(None, None)`` for no such setting."""
    hints = typing.get_type_hints(exp.config_type)
    key = str(key).strip()
    name = key if key in hints else key.replace("-", "_") if key.replace("-", "_") in hints else None
    if name is not None:
        return name, next((opt for opt in exp.options if opt.field == name), None)
    options = {n.lstrip("-"): opt for opt in exp.options for flag in opt.flags for n in flag.split("/")}
    opt = options.get(key)
    if opt is not None and len(opt.fields) == 1:
        return opt.fields[0], opt
    return None, opt


def field_type(exp: Any, name: str) -> Any:
    """A config field's type (its annotation, ``None`` removed from a union)."""
    hint = typing.get_type_hints(exp.config_type)[name]
    kinds = [k for k in typing.get_args(hint) if k is not type(None)] if isinstance(hint, types.UnionType) \
        or typing.get_origin(hint) is typing.Union else [hint]
    return kinds[0] if len(kinds) == 1 else hint


def _typed(hint: Any, value: Any, where: str) -> Any:
    """``value`` (as TOML or JSON gives it) as a value of the type ``hint``, or a one-line error."""
    kinds = typing.get_args(hint) if isinstance(hint, types.UnionType) or typing.get_origin(hint) is typing.Union \
        else (hint,)
    problems = []
    for kind in kinds:
        if kind is type(None):
            continue
        try:
            return _one(kind, value)
        except (TypeError, ValueError) as exc:
            problems.append(str(exc))
    raise WorkbenchError(f"{where}: {' or '.join(dict.fromkeys(problems))}, got {value!r}")


def _one(kind: Any, value: Any) -> Any:
    if kind is bool:
        if isinstance(value, bool):
            return value
        raise TypeError("must be true or false")
    if kind is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise TypeError("must be a whole number")
    if kind is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            if not math.isfinite(value):
                raise ValueError("must be a finite number")
            return float(value)
        raise TypeError("must be a number")
    if kind is str:
        if isinstance(value, str):
            return value
        raise TypeError("must be text")
    if kind is Path:
        if isinstance(value, str) and value.strip():
            return Path(value).expanduser()
        raise TypeError("must be a path (non-empty text)")
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        items = split_list(value) if isinstance(value, str) and args[-1:] == (Ellipsis,) else value
        if not isinstance(items, (list, tuple)):
            raise TypeError("must be a list")
        if args[-1:] == (Ellipsis,):
            return tuple(_one(args[0], v) for v in items)
        if len(items) != len(args):
            raise ValueError(f"must be a list of {len(args)}")
        return tuple(_one(a, v) for a, v in zip(args, items, strict=True))
    raise TypeError(f"cannot be set from a file ({kind})")


def loads(exp: Any, config: str | Path | Mapping[str, Any] | None) -> dict[str, Any]:
    """The settings of a config file's path, or of a mapping given in Python; none for ``None``."""
    if config is None:
        return {}
    if isinstance(config, Mapping):
        return settings(exp, config, "config")
    return settings(exp, read(config), f"--config {config}")


def dumps_toml(values: Mapping[str, Any]) -> str:
    """Settings as a flat TOML table (what ``best.toml`` holds): numbers, booleans, text and lists."""

    def show(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(float(v)) if isinstance(v, float) else str(v)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(show(x) for x in v) + "]"
        return json.dumps(str(v))

    return "".join(f"{k} = {show(v)}\n" for k, v in values.items() if v is not None)

