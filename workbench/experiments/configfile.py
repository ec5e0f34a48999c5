"""Moved to :mod:`workbench.config.files`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.config import files as _new

sys.modules[__name__] = moved(__name__, _new)
