"""Moved to :mod:`workbench.experiments.omni.algorithms.triangulation`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.omni.algorithms import triangulation as _new

sys.modules[__name__] = moved(__name__, _new)
