"""The registry: experiment name -> its :class:`~workbench.core.experiment.Experiment`.

Adding an experiment is its own package (with an ``experiment.py`` defining ``EXPERIMENT``) and
one function here that imports it; or, from an installed package, an entry point of the group
``workbench.experiments`` named after the experiment, pointing at its ``EXPERIMENT`` (the object)
or its ``experiment`` module. Each is imported when first asked for (``experiment.py`` modules
import nothing heavy at the top, so listing them is quick), and its declaration is checked then,
its parts on their first use (:meth:`~workbench.core.experiment.Experiment.check_declaration`).
"""

from __future__ import annotations

import copyreg
import dataclasses
import functools
from typing import Any

from workbench import loading
from workbench.core.estimator import Color, Estimator, one
from workbench.errors import WorkbenchError

GROUP = "workbench.experiments"


def _omni():
    from workbench.experiments.omni.experiment import EXPERIMENT

    return EXPERIMENT


def _sea():
    from workbench.experiments.sea.experiment import EXPERIMENT

    return EXPERIMENT


def _terrain():
    from workbench.experiments.terrain.experiment import EXPERIMENT

    return EXPERIMENT


REGISTRY = {"omni": _omni, "sea": _sea, "terrain": _terrain}
"""The built-in experiments, name -> a function that imports its declaration."""


def installed() -> dict:
    """Experiments installed packages register (entry points, not yet loaded), by name; a
    built-in's name is not taken."""
    return {k: ep for k, ep in loading.entry_points(GROUP).items() if k not in REGISTRY}


def names() -> list[str]:
    return [*REGISTRY, *installed()]


@functools.cache
def _builtin(name: str):
    return REGISTRY[name]().check_declaration(parts=False)


def get(name: str) -> Any:
    """The experiment called ``name``, its declaration checked on first use.

    Args:
        name: a built-in's name or an installed experiment's (entry point group ``workbench.experiments``).

    Returns:
        The experiment's :class:`~workbench.core.experiment.Experiment`.

    Raises:
        WorkbenchError: no experiment by that name (the error names the others), or its declaration is wrong.
    """
    if name in REGISTRY:
        return _builtin(name)
    plugins = installed()
    if name not in plugins:
        raise WorkbenchError(f"unknown experiment {name!r}; choose one of {', '.join(names())}")
    obj = loading.load_entry_point(plugins[name], f"experiment {name!r}")
    exp = getattr(obj, "EXPERIMENT", obj)
    if getattr(exp, "name", None) != name:
        raise WorkbenchError(f"installed experiment {name!r} is not an Experiment named {name!r}")
    return exp.check_declaration(parts=False)


def all_experiments() -> list:
    return [get(n) for n in names()]


@functools.lru_cache(maxsize=256)
def find(experiment: str, ref: str, name: str, color: Color | None = None) -> Estimator:
    """An estimator found again from its ref (in a worker process): unpickling goes here."""
    est = one(get(experiment), ref)
    if est.name != name or (color is not None and est.color != tuple(color)):
        est = dataclasses.replace(est, name=name, color=tuple(color) if color is not None else est.color)
    return est


def _reduce(est: Estimator):
    """An estimator with a ref pickles as how to find it again (:func:`find`); one without by value."""
    if est.ref is not None:
        return find, (est.experiment, est.ref, est.name, est.color)
    return est.__reduce__()


copyreg.pickle(Estimator, _reduce)
