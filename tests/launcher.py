"""Running the ``workbench`` command as a user does, for the end-to-end tests."""

import subprocess
import sys

from workbench.paths import data_root

DATA = data_root()


def wb(*args, cwd=None, timeout: int = 900) -> subprocess.CompletedProcess:
    """``python -m workbench ARGS`` in a fresh process; output captured as text."""
    return subprocess.run([sys.executable, "-m", "workbench", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout)
