"""Where real data lives: ``--data`` beats ``WORKBENCH_DATA`` beats ``../shared/data``."""

from __future__ import annotations

import os
from pathlib import Path

from workbench.errors import DataNotFound, WorkbenchError

PROJECT_ROOT = Path(__file__).resolve().parent.parent


def data_root() -> Path:
    """The data root: ``$WORKBENCH_DATA`` if set, else ``shared/data`` beside the project."""
    env = os.environ.get("WORKBENCH_DATA")
    if env:
        return Path(env).expanduser()
    return PROJECT_ROOT.parent / "shared" / "data"


def data_file(given: Path | None, default_relative: str) -> Path:
    """Resolve a data file: the user's path, else ``default_relative`` under the data root."""
    path = Path(given).expanduser() if given is not None else data_root() / default_relative
    if not path.exists():
        hint = "" if given is not None else " (set WORKBENCH_DATA or pass --data)"
        raise DataNotFound(f"data file not found: {path}{hint}")
    if not path.is_file():
        raise WorkbenchError(f"not a file: {path}")
    return path
