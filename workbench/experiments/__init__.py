"""The experiments, one package each: ``omni`` (paper 000), ``terrain`` (001) and ``sea`` (002).

The framework they stand on lives in :mod:`workbench.core` (the contract, the estimator row, the
registry), :mod:`workbench.config`, :mod:`workbench.metrics` and :mod:`workbench.io`; the registry
is :mod:`workbench.core.registry`. The names this package gave before (``get``, ``names``,
``REGISTRY``, ...) still work for one release, with a :class:`~workbench._moved.MovedWarning`.
"""

from __future__ import annotations

_REGISTRY_NAMES = ("get", "names", "installed", "all_experiments", "REGISTRY", "GROUP")


def __getattr__(name: str):
    if name in _REGISTRY_NAMES:
        from workbench._moved import moved
        from workbench.core import registry

        return getattr(moved(f"workbench.experiments.{name}", registry), name)
    raise AttributeError(f"module 'workbench.experiments' has no attribute {name!r}")
