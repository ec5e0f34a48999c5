"""Moved to :mod:`workbench.experiments.omni.readers.tum`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.omni.readers import tum as _new

sys.modules[__name__] = moved(__name__, _new)
