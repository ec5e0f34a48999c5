"""Moved to :mod:`workbench.experiment_command`; this path is kept for one release and warns."""

import sys

from workbench import experiment_command as _new
from workbench._moved import moved

sys.modules[__name__] = moved(__name__, _new)
