import numpy as np
import pytest

from workbench.core.threads import one_blas_thread
from workbench.experiments.sea.config import SeaConfig

# one BLAS thread in each test worker for its whole life, as the command and the runs use
# (workbench.core.threads): with a worker per core, numpy's thread per core only spins beside the
# other worker (the heavy numerical files took 11 % less CPU so)
one_blas_thread().__enter__()


@pytest.fixture
def paper_cfg() -> SeaConfig:
    return SeaConfig().validate()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


SLOW_FIRST = ("test_tutorials.py", "test_browser.py", "test_sweeps.py", "test_relocation.py", "test_replay.py",
              "test_bounds.py", "test_live.py", "test_selftune.py", "test_bootstrap.py", "test_terrain_measure.py",
              "test_long_logs.py", "test_omni_log.py", "test_tune.py", "test_misread_starts.py", "test_omni_cli.py",
              "test_omni_math.py", "test_notebook.py", "test_hostile.py")
"""The files that take minutes, longest first (each file's time in a full suite, measured): with a
file per worker (``-n auto --dist loadfile``, and ``--no-loadscope-reorder``, without which xdist
orders the files by their count of tests instead) the short ones then fill in beside them, instead
of one long file running alone at the end."""


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(SLOW_FIRST)))  # stable: order within a file kept
