"""Moved to :mod:`workbench.core.components`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.core import components as _new

sys.modules[__name__] = moved(__name__, _new)
