"""Moved to :mod:`workbench.metrics.tables`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.metrics import tables as _new

sys.modules[__name__] = moved(__name__, _new)
