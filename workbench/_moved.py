"""The old module paths of a release that moved them: each warns once when imported and is then
the new module itself (the same object, so a patch through either path holds)."""

from __future__ import annotations

import warnings
from types import ModuleType


class MovedWarning(FutureWarning):
    """A module imported by a path that the next release removes (shown by default: a plugin's
    author reads it on the command line, not only under a test runner)."""


def moved(old: str, new: ModuleType) -> ModuleType:
    """Warn that ``old`` is now ``new`` and give ``new`` (a shim's ``sys.modules[__name__]``)."""
    warnings.warn(f"{old} has moved to {new.__name__}; the old path goes in the next release",
                  MovedWarning, stacklevel=3)
    return new
