"""The registry: experiment name -> its :class:`~workbench.experiments.contract.Experiment`.

Adding an experiment is its own package (with an ``experiment.py`` defining ``EXPERIMENT``)
and one line here. Each is imported when first asked for; ``experiment.py`` modules import
nothing heavy at the top, so listing them is quick.
"""

from __future__ import annotations

import importlib

from workbench.errors import WorkbenchError

REGISTRY: dict[str, str] = {
    "omni": "workbench.experiments.omni.experiment",
    "sea": "workbench.experiments.sea.experiment",
    "terrain": "workbench.experiments.terrain.experiment",
}


def names() -> list[str]:
    return list(REGISTRY)


def get(name: str):
    """The experiment called ``name`` (a one-line error naming the others if there is none)."""
    if name not in REGISTRY:
        raise WorkbenchError(f"unknown experiment {name!r}; choose one of {', '.join(REGISTRY)}")
    return importlib.import_module(REGISTRY[name]).EXPERIMENT


def all_experiments() -> list:
    return [get(n) for n in REGISTRY]
