"""Moved to :mod:`workbench.io.text`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.io import text as _new

sys.modules[__name__] = moved(__name__, _new)
