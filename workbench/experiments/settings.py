"""Moved to :mod:`workbench.config.settings`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.config import settings as _new

sys.modules[__name__] = moved(__name__, _new)
