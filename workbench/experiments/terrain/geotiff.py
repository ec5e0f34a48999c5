"""Moved to :mod:`workbench.experiments.terrain.products.geotiff`; this path is kept for one release and warns."""

import sys

from workbench._moved import moved
from workbench.experiments.terrain.products import geotiff as _new

sys.modules[__name__] = moved(__name__, _new)
