"""Moved to :mod:`workbench.metrics.base`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.metrics import base as _new

sys.modules[__name__] = moved(__name__, _new)
