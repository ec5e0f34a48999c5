"""Moved to :mod:`workbench.metrics.statistics`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.metrics import statistics as _new

sys.modules[__name__] = moved(__name__, _new)
