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
"""

from workbench.version import __version__ as __version__

__all__ = ["run", "configure", "experiment", "estimator", "metric", "Values", "Result", "show", "compare"]


def __getattr__(name: str):
    if name in ("run", "configure", "Result"):
        from workbench import api

        return getattr(api, name)
    if name == "experiment":
        from workbench.experiments import get

        return get
    if name == "estimator":
        from workbench.experiments.estimator import estimator

        return estimator
    if name == "show":
        from workbench.recording.notebook import show

        return show
    if name == "compare":
        from workbench.tools.compare import write

        return write
    if name in ("metric", "Values"):
        from workbench.experiments import metric

        return getattr(metric, name)
    import importlib.util

    if not name.startswith("_") and importlib.util.find_spec(f"workbench.{name}") is None:
        import workbench.api

        try:
            return workbench.api.command(name)  # a command an experiment declares (terrain's measure)
        except AttributeError:
            pass
    raise AttributeError(f"module 'workbench' has no attribute {name!r}")
