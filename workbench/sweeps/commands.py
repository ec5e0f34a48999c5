"""Moved to :mod:`workbench.sweeps.cli`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.sweeps import cli as _new

sys.modules[__name__] = moved(__name__, _new)
