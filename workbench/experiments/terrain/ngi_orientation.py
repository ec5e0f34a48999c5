"""Moved to :mod:`workbench.experiments.terrain.readers.ngi_orientation`; kept for one release, with a warning."""

import sys

from workbench._moved import moved
from workbench.experiments.terrain.readers import ngi_orientation as _new

sys.modules[__name__] = moved(__name__, _new)
