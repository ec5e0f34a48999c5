"""Moved to :mod:`workbench.experiments.omni.algorithms.fixed_lag`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.omni.algorithms import fixed_lag as _new

sys.modules[__name__] = moved(__name__, _new)
