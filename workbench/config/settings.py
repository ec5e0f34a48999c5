"""An experiment's settings: scenarios (named sets of defaults), fields whose default depends on
the scenario, command-line options (one config field each), and the one converter of a config
to JSON (what recordings, metrics and sweeps store).

An experiment's config is a dataclass with the fields ``scenario``, ``seed``, ``runs`` and
``estimators``; it inherits :class:`Config` (``to_json``), declares scenario-dependent fields
with :func:`by_scenario` and fills them in ``__post_init__`` by :func:`apply_scenario`, and
has a ``validate()`` that raises a one-line error for any value out of range.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from workbench.errors import WorkbenchError


@dataclass(frozen=True)
class Scenario:
    """A named set of defaults. ``defaults`` maps config fields to values; ``real_data``: it
    reads data that may be absent (the demo skips it then, and only then)."""

    name: str
    description: str
    defaults: Mapping[str, Any] = field(default_factory=dict)
    real_data: bool = False


def by_scenario(base: Any) -> Any:
    """A config field whose default depends on the scenario: ``base`` unless the scenario's
    :class:`Scenario` defaults name another value. It reads as ``None`` until the config's
    ``__post_init__`` calls :func:`apply_scenario`, which fills it (the one place it happens)."""
    return field(default=None, metadata={"base": base})


def scenario_fields(config_type: type) -> dict[str, Any]:
    """The fields declared with :func:`by_scenario` and their base defaults."""
    return {f.name: f.metadata["base"] for f in dataclasses.fields(config_type) if "base" in f.metadata}


def apply_scenario(cfg: Any, scenarios: Mapping[str, Scenario]) -> None:
    """Fill every :func:`by_scenario` field left ``None`` from ``cfg.scenario``'s defaults (or the
    base). An unknown scenario is a one-line error here, so a config never exists with one; an
    empty one too (``--scenario ''``: a typo, never "the default")."""
    if not isinstance(cfg.scenario, str) or not cfg.scenario.strip():
        raise WorkbenchError(f"--scenario {cfg.scenario!r} is empty; choose one of {', '.join(scenarios)}")
    if cfg.scenario not in scenarios:
        raise WorkbenchError(f"unknown scenario {cfg.scenario!r}; choose one of {', '.join(scenarios)}")
    defaults = scenarios[cfg.scenario].defaults
    for name, base in scenario_fields(type(cfg)).items():
        if getattr(cfg, name) is None:
            setattr(cfg, name, defaults.get(name, base))


def default_text(config_type: type, scenarios: Mapping[str, Scenario], name: str) -> str:
    """How a field's default reads in ``--help``: ``[3]``, or ``[3; ais 20]`` where a scenario differs."""
    fields = {f.name: f for f in dataclasses.fields(config_type)}
    f = fields[name]
    if "base" in f.metadata:
        base = f.metadata["base"]
        other = [f"{s} {_show(sc.defaults[name])}" for s, sc in scenarios.items()
                 if name in sc.defaults and sc.defaults[name] != base]
        return "[" + "; ".join([_show(base), *other]) + "]"
    if f.default is not dataclasses.MISSING:
        return f"[{_show(f.default)}]" if f.default is not None else ""
    return ""


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, tuple) and len(value) == 2 and all(isinstance(v, int) for v in value):
        return f"{value[0]}x{value[1]}"  # an image size
    if isinstance(value, tuple):
        return ",".join(map(str, value))
    return f"{value:g}" if isinstance(value, float) else str(value)


def assumed(data: Any, cfg: Any, table: Mapping[str, tuple[str, Callable[[float], Any]]]) -> Any:
    """``data`` with the noise the estimators assume where ``cfg`` sets it: ``table`` maps a config
    field (``assume_*``, None: the data's own) to the dataset's attribute and the conversion of the
    field's value to it (units). The data unchanged (the same object) where none is set."""
    changes = {attr: convert(getattr(cfg, name)) for name, (attr, convert) in table.items()
               if getattr(cfg, name, None) is not None}
    return dataclasses.replace(data, **changes) if changes else data


def check_assumed(cfg: Any, flags: Mapping[str, str]) -> None:
    """Each ``assume_*`` field (``flags``: field -> its option) None or a positive finite number;
    a one-line error naming the option otherwise."""
    import math

    for name, flag in flags.items():
        value = getattr(cfg, name)
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise WorkbenchError(f"{flag} must be a positive number (what the estimators assume), got {value}")


def config_json(cfg: Any) -> dict:
    """A config as JSON-ready values: every field, paths as text, tuples as lists (the one
    converter: recordings, metrics and sweeps store what it gives)."""

    def plain(value: Any) -> Any:
        if isinstance(value, Path):
            return str(value)
        if isinstance(value, (tuple, list)):
            return [plain(v) for v in value]
        if isinstance(value, dict):
            return {k: plain(v) for k, v in value.items()}
        return value

    return {f.name: plain(getattr(cfg, f.name)) for f in dataclasses.fields(cfg)}


ESTIMATOR_TIMEOUT = 600.0
"""The default of ``--estimator-timeout`` (s). Measured on the default scenarios (2 cores): the
slowest built-in per run is sea's isam2, 0.25 s; omni's gtsam-batch, 14 s idle and up to 33 s with
the machine loaded 4x over; terrain's recurrent search with the search it shares, 19 s on a first
run that compiles its Numba kernel (6 s once cached). 600 s is 32x the slowest idle and 18x it
loaded, room for longer scenarios, and still ends a hung estimator within minutes."""


def parse_timeout(text: Any) -> float:
    """``--estimator-timeout``: seconds (a positive number), or ``0`` / ``none`` / ``off`` /
    ``inf``: no limit (stored as 0)."""
    low = str(text).strip().lower()
    if low in ("none", "off", "no", "never", "inf", "infinity", "0"):
        return 0.0
    try:
        value = float(low)
    except ValueError:
        raise ValueError(f"seconds, or none for no limit; got {text!r}") from None
    if value != value or value < 0:  # NaN, negative
        raise ValueError(f"seconds (at least 0; 0 or none: no limit), got {text!r}")
    return 0.0 if value == 0 or value == float("inf") else value


@dataclass
class Config:
    """What every experiment's config dataclass inherits: the fields every experiment has (a
    subclass gives ``scenario`` its default, the first scenario's name) and :meth:`to_json`.

    ``estimators``: the selection (empty: the experiment's defaults); ``add_metrics``: metric
    plugins (``module:function`` / ``file.py:function`` specs) beside the experiment's own;
    ``tune_noise``: before the runs, the noise the data identify estimated on run 0's data by a
    filter's likelihood (:mod:`workbench.core.selftune`) and told to every estimator;
    ``estimator_timeout``: the seconds one estimator may take on one run's data before it is
    stopped and left out like one that raised (0: no limit; :data:`ESTIMATOR_TIMEOUT`);
    ``bootstrap``: resamples per run simulated from the run's own answer, a truth-free NEES
    (:mod:`workbench.metrics.bootstrap`; 0: none)."""

    scenario: str = ""
    seed: int = 0
    runs: int = 1
    estimators: tuple[str, ...] = ()
    add_metrics: tuple[str, ...] = ()
    tune_noise: bool = by_scenario(False)  # estimate the noise the data identify first (tuning.selftune)
    estimator_timeout: float = ESTIMATOR_TIMEOUT
    bootstrap: int = 0  # resamples per run from the run's own answer: a truth-free NEES (experiments.bootstrap)

    def to_json(self) -> dict:
        return config_json(self)


@dataclass(frozen=True)
class Option:
    """One command-line option of an experiment, setting one config field (or, for an
    experiment's ``extras``, one value handed to its hooks).

    ``type`` is what the command line parses (``str`` for values ``parse`` turns into the
    field's type); ``flag`` defaults to ``--field-name``; ``switch`` is ``"--on/--off"`` for a
    boolean; ``sets`` names the config fields it sets where that is not ``field`` alone.
    Every option defaults to "not given", so the scenario's default applies."""

    field: str
    help: str
    type: type = float
    flag: str | None = None
    parse: Callable[[Any], Any] | None = None
    switch: str | None = None
    sets: tuple[str, ...] = ()

    @property
    def fields(self) -> tuple[str, ...]:
        return self.sets or (self.field,)

    @property
    def flags(self) -> tuple[str, ...]:
        if self.switch:
            return (self.switch,)
        return (self.flag or "--" + self.field.replace("_", "-"),)

    def described(self, config_type: type, scenarios: Mapping[str, Scenario]) -> str:
        """The help text with the default appended (``[3; ais 20]``), where the help gives none."""
        if "[" in self.help or self.fields[0] not in {f.name for f in dataclasses.fields(config_type)}:
            return self.help
        return f"{self.help} {default_text(config_type, scenarios, self.fields[0])}".strip()

    def value(self, given: Any) -> Any:
        """The config value of what the command line parsed (a one-line error if ``parse`` fails)."""
        if given is not None and self.type is Path:
            # typed as text on the command line (typer would make '' the current folder, '.')
            if not str(given).strip():
                raise WorkbenchError(f"{self.flags[0]} needs a path, got ''")
            given = Path(str(given))
        if given is None or self.parse is None:
            return given
        try:
            return self.parse(given)
        except (ValueError, TypeError) as exc:
            raise WorkbenchError(f"{self.flags[0]}: {exc}") from None


COMMON: tuple[Option, ...] = (
    Option("estimator_timeout", "Seconds one estimator may take on one run's data; past it, it is stopped, named and "
           "left out like one that raised (exit 3; its thread is abandoned). 0 or none: no limit.", str,
           parse=parse_timeout),
    Option("bootstrap", "Resamples per run simulated from the run's own answer (its smoother's trajectory and map, the "
           "noise the data identify); every estimator reruns on each and its NEES there is `bootstrap_nees`, a "
           "truth-free check that its covariance covers its error. Costs B runs of every estimator. 0: none.", int),
)
"""Options of every experiment's config fields beyond its own (:attr:`Experiment.settable`): on
every experiment command, in sweeps' ``--grid`` / ``--set``, checked by ``validate``."""
