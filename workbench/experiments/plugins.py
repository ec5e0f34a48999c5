"""Kept for one release: plugin resolution now lives in :mod:`workbench.experiments.estimator`
(estimators) and :mod:`workbench.experiments.metric` (metrics), the loading of specs and entry
points in :mod:`workbench.loading`. Import from there."""

from workbench.experiments.estimator import (  # noqa: F401
    GROUP,
    PLUGIN_COLORS,
    estimator,
    find,
    from_function,
    installed,
    one,
    plugin_color,
    resolve,
)
from workbench.loading import load  # noqa: F401
