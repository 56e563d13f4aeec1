import numpy as np
import pytest

from acoustic_sim.acoustics.hrtf import HRTF


@pytest.fixture(scope="session")
def kemar() -> HRTF:
    return HRTF.load("kemar")


@pytest.fixture(scope="session")
def spherical() -> HRTF:
    return HRTF.spherical_head()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
