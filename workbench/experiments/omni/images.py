"""Moved to :mod:`workbench.experiments.omni.imaging.stage`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.omni.imaging import stage as _new

sys.modules[__name__] = moved(__name__, _new)
