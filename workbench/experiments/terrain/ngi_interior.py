"""Moved to :mod:`workbench.experiments.terrain.readers.ngi_interior`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.terrain.readers import ngi_interior as _new

sys.modules[__name__] = moved(__name__, _new)
