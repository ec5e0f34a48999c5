"""Moved to :mod:`workbench.experiments.omni.readers.log`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.omni.readers import log as _new

sys.modules[__name__] = moved(__name__, _new)
