"""Moved to :mod:`workbench.metrics.truthfree`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.metrics import truthfree as _new

sys.modules[__name__] = moved(__name__, _new)
