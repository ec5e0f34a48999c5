"""A tuning study's search space: ``--param NAME=LOW:HIGH[:log]`` over any number setting.

``NAME`` is a config field or its option's name (``sigma-acc``, ``assume_sigma_acc``). A noise
that has an ``assume_`` twin (what the estimators assume, :meth:`Experiment.assumed`) is tuned
as the twin: the data stay as they were made (the same draws in every trial, on a simulation as
on a log) and only the estimators are told another value, which is what tuning means. Every
bound is checked before any work: a one-line error for a range that is empty (LOW >= HIGH), a
log scale with a bound that is not positive, a setting that is not a number, or a bound the
config itself refuses (its ``validate``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from workbench.config import files as configfile
from workbench.errors import WorkbenchError

FIXED = ("seed", "runs", "estimators", "scenario")
"""Settings a study owns or that are not numbers to search over."""


@dataclass(frozen=True)
class Param:
    """One searched setting: the config field it sets, its range, its scale."""

    key: str          # as given (``sigma-acc``)
    field: str        # the config field tuned (``assume_sigma_acc``)
    low: float
    high: float
    log: bool = False
    integer: bool = False

    def suggest(self, trial: Any) -> float | int:
        if self.integer:
            return trial.suggest_int(self.field, int(self.low), int(self.high), log=self.log)
        return trial.suggest_float(self.field, self.low, self.high, log=self.log)

    def distribution(self) -> Any:
        import optuna

        if self.integer:
            return optuna.distributions.IntDistribution(int(self.low), int(self.high), log=self.log)
        return optuna.distributions.FloatDistribution(self.low, self.high, log=self.log)

    def to_json(self) -> dict:
        return {"key": self.key, "field": self.field, "low": self.low, "high": self.high, "log": self.log,
                "integer": self.integer}

    def contains(self, value: Any) -> bool:
        return isinstance(value, (int, float)) and self.low <= value <= self.high


def parse_one(exp: Any, spec: str) -> Param:
    """``NAME=LOW:HIGH[:log]`` as a :class:`Param` of ``exp``'s config (one-line errors)."""
    text = str(spec).strip()
    if not text.isprintable():
        raise WorkbenchError(f"--param {text!r}: a control character; it must look like NAME=LOW:HIGH[:log]")
    key, eq, rng = text.partition("=")
    parts = [p.strip() for p in rng.split(":")]
    if not eq or not key.strip() or len(parts) not in (2, 3):
        raise WorkbenchError(f"--param {text!r} must look like NAME=LOW:HIGH or NAME=LOW:HIGH:log")
    key = key.strip()
    name, _ = configfile.resolve(exp, key)
    if name is None:
        raise WorkbenchError(f"--param {key}: {exp.name} has no number setting {key!r} "
                             f"(a setting of several fields, or none); see `workbench {exp.name} --help`")
    if name in FIXED:
        raise WorkbenchError(f"--param {key}: a study sets {name} itself")
    kind = configfile.field_type(exp, name)
    if kind not in (int, float) or kind is bool:
        raise WorkbenchError(f"--param {key}: {name} is not a number setting ({getattr(kind, '__name__', kind)}); "
                             "only numbers are searched")
    twin = f"assume_{name}"
    fields = {f for f in exp.config_type.__dataclass_fields__}
    tuned = twin if twin in fields else name
    scale = parts[2].lower() if len(parts) == 3 else ""
    if scale not in ("", "log"):
        raise WorkbenchError(f"--param {key}: the third part is 'log' or nothing, not {parts[2]!r}")
    try:
        low, high = float(parts[0]), float(parts[1])
    except ValueError:
        raise WorkbenchError(f"--param {key}: LOW and HIGH must be numbers, "
                             f"got {parts[0]!r} and {parts[1]!r}") from None
    if not (math.isfinite(low) and math.isfinite(high)):
        raise WorkbenchError(f"--param {key}: LOW and HIGH must be finite, got {low:g} and {high:g}")
    if low >= high:
        raise WorkbenchError(f"--param {key}: LOW must be below HIGH, got {low:g}:{high:g}")
    if scale == "log" and low <= 0:
        raise WorkbenchError(f"--param {key}: a log scale needs positive bounds, got {low:g}:{high:g}")
    integer = kind is int
    if integer and (low != int(low) or high != int(high)):
        raise WorkbenchError(f"--param {key}: {name} is a whole number; give whole bounds, got {low:g}:{high:g}")
    return Param(key, tuned, low, high, scale == "log", integer)


def parse(exp: Any, specs: list[str], base: dict[str, Any], scenario: str | None) -> list[Param]:
    """Every ``--param``, each bound checked by the config itself (built at LOW and at HIGH)."""
    if not specs:
        raise WorkbenchError("nothing to tune: give --param NAME=LOW:HIGH[:log] (one or more)")
    params = [parse_one(exp, s) for s in specs]
    seen: set[str] = set()
    for p in params:
        if p.field in seen:
            raise WorkbenchError(f"--param {p.key}: {p.field} is searched twice")
        seen.add(p.field)
    for p in params:
        for bound in (p.low, p.high):
            value = int(bound) if p.integer else bound
            exp.validate(exp.configure(scenario, **{**base, p.field: value}))
    return params


def notes(params: list[Param]) -> list[str]:
    """What the space says of itself: the noises tuned as what the estimators assume."""
    return [f"{p.key}: tuned as what the estimators assume ({p.field}); the data stay as they were made"
            for p in params if p.field.startswith("assume_") and not p.key.replace("-", "_").startswith("assume_")]
