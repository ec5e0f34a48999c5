"""The workbench: paper estimators against GTSAM baselines, recorded to Rerun.

The Python API (imported on first use, so ``import workbench`` stays light):

* ``workbench.run(experiment, scenario=..., runs=..., estimators=[...], out=..., **overrides)``:
  run an experiment, your own estimators beside the built-ins (:func:`workbench.api.run`);
* ``workbench.configure(experiment, scenario, **overrides)``: the config it would use;
* ``workbench.experiment(name)``: the experiment's contract (scenarios, estimator table, types);
* ``@workbench.estimator(description=..., causal=..., covariances=...)``: describe your estimator;
* ``@workbench.metric(unit=..., reduce=..., dimension=...)``: describe your metric, a function
  ``(data, estimate) -> workbench.Values`` (``workbench.run(..., add_metrics=[fn])`` or an entry
  point of the group ``workbench.metrics``);
* ``workbench.measure(model, points=...)``, and any command an experiment declares;
* ``workbench.show(path)``: a recording inline in a Jupyter notebook, in its own layout;
* ``workbench.compare([a, b], out, labels=..., pairs=...)``: one recording of several runs side by
  side, overlaid and differenced (the ``workbench compare`` command).

The plugin surface, for your own estimator, metric or experiment (each from the package that holds it):

* ``Experiment``, ``Parts``, ``Demo``, ``Preset``, ``Command``, ``RunResult``, ``RunSummary``
  (:mod:`workbench.core`); ``Estimator``, ``RunContext``, ``EstimateError`` and the estimate checks
  ``as_array``, ``whole_rows``, ``psd`` (:mod:`workbench.core.estimator`);
* ``Config``, ``Option``, ``Scenario``, ``by_scenario`` (:mod:`workbench.config.settings`);
* ``Metric``, ``MetricContext``, ``Values`` (:mod:`workbench.metrics.base`).
"""

from workbench.version import __version__ as __version__

_SURFACE = {
    "workbench.core.experiment": ("Experiment", "run_estimators"),
    "workbench.core.parts": ("Parts", "Demo", "Preset", "Command", "declare"),
    "workbench.core.results": ("RunResult", "RunSummary"),
    "workbench.core.estimator": ("Estimator", "RunContext", "EstimateError", "as_array", "whole_rows", "psd",
                                 "estimator", "table"),
    "workbench.config.settings": ("Config", "Option", "Scenario", "by_scenario"),
    "workbench.metrics.base": ("Metric", "MetricContext", "Values", "metric"),
    "workbench.api": ("run", "configure", "Result"),
    "workbench.core.registry": ("experiment",),
    "workbench.recording.notebook": ("show",),
    "workbench.tools.compare": ("compare",),
}
"""Each public name -> the module that holds it (imported on first use, so ``import workbench`` stays light)."""

__all__ = sorted({n for names in _SURFACE.values() for n in names})


def _load(module: str):
    """The module holding a public name (each imported statically, so the import test sees the edge)."""
    if module == "workbench.core.experiment":
        from workbench.core import experiment as m
    elif module == "workbench.core.parts":
        from workbench.core import parts as m
    elif module == "workbench.core.results":
        from workbench.core import results as m
    elif module == "workbench.core.estimator":
        from workbench.core import estimator as m
    elif module == "workbench.config.settings":
        from workbench.config import settings as m
    elif module == "workbench.metrics.base":
        from workbench.metrics import base as m
    elif module == "workbench.api":
        from workbench import api as m
    elif module == "workbench.core.registry":
        from workbench.core import registry as m
    elif module == "workbench.recording.notebook":
        from workbench.recording import notebook as m
    else:
        from workbench.tools import compare as m
    return m


_RENAMED = {"experiment": "get", "compare": "write"}


def __getattr__(name: str):
    for module, names in _SURFACE.items():
        if name in names:
            return getattr(_load(module), _RENAMED.get(name, name))
    if not name.startswith("_") and name not in ("api", "cli", "core", "config", "metrics", "io", "recording",
                                                 "estimation", "experiments", "sweeps", "tuning", "tools",
                                                 "errors", "loading", "paths", "version", "commands"):
        from workbench import api

        try:
            return api.command(name)  # a command an experiment declares (terrain's measure)
        except AttributeError:
            pass
    raise AttributeError(f"module 'workbench' has no attribute {name!r}")
