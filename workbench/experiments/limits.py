"""Moved to :mod:`workbench.config.checks`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.config import checks as _new

sys.modules[__name__] = moved(__name__, _new)
