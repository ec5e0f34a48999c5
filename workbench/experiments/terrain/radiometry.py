"""Moved to :mod:`workbench.experiments.terrain.algorithms.radiometry`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.terrain.algorithms import radiometry as _new

sys.modules[__name__] = moved(__name__, _new)
