"""Moved to :mod:`workbench.metrics.curves`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.metrics import curves as _new

sys.modules[__name__] = moved(__name__, _new)
