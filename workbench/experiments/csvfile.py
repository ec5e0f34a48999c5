"""Moved to :mod:`workbench.io.csvfiles`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.io import csvfiles as _new

sys.modules[__name__] = moved(__name__, _new)
