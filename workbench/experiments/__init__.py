"""The registry: experiment name -> its :class:`~workbench.experiments.contract.Experiment`.

Adding an experiment is its own package (with an ``experiment.py`` defining ``EXPERIMENT``)
and one line here; or, from an installed package, an entry point of the group
``workbench.experiments`` named after the experiment, pointing at its ``EXPERIMENT`` (the
object) or its ``experiment`` module. Each is imported when first asked for; ``experiment.py``
modules import nothing heavy at the top, so listing them is quick.
"""

from __future__ import annotations

import importlib

from workbench import loading
from workbench.errors import WorkbenchError

GROUP = "workbench.experiments"
REGISTRY: dict[str, str] = {
    "omni": "workbench.experiments.omni.experiment",
    "sea": "workbench.experiments.sea.experiment",
    "terrain": "workbench.experiments.terrain.experiment",
}


def installed() -> dict:
    """Experiments installed packages register (entry points, not yet loaded), by name; a
    built-in's name is not taken."""
    return {k: ep for k, ep in loading.entry_points(GROUP).items() if k not in REGISTRY}


def names() -> list[str]:
    return [*REGISTRY, *installed()]


def get(name: str):
    """The experiment called ``name`` (a one-line error naming the others if there is none)."""
    if name in REGISTRY:
        return importlib.import_module(REGISTRY[name]).EXPERIMENT
    plugins = installed()
    if name not in plugins:
        raise WorkbenchError(f"unknown experiment {name!r}; choose one of {', '.join(names())}")
    obj = loading.load_entry_point(plugins[name], f"experiment {name!r}")
    exp = getattr(obj, "EXPERIMENT", obj)
    if getattr(exp, "name", None) != name:
        raise WorkbenchError(f"installed experiment {name!r} is not an Experiment named {name!r}")
    return exp


def all_experiments() -> list:
    return [get(n) for n in names()]
