"""Moved to :mod:`workbench.tuning.cli`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.tuning import cli as _new

sys.modules[__name__] = moved(__name__, _new)
