"""Moved to :mod:`workbench.experiments.terrain.algorithms.ba`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.terrain.algorithms import ba as _new

sys.modules[__name__] = moved(__name__, _new)
