import numpy as np
import pytest

from workbench.experiments.sea.config import SeaConfig


@pytest.fixture
def paper_cfg() -> SeaConfig:
    return SeaConfig().validate()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
