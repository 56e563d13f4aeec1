from pathlib import Path

import numpy as np
import pytest

from acoustic_sim.world.snapshot import choose_gl_backend

# An offscreen OpenGL backend, chosen before any test module imports MuJoCo (several do at
# collection): otherwise MuJoCo falls back to GLFW, which warns without a display.
choose_gl_backend()

from acoustic_sim.acoustics.hrtf import HRTF  # noqa: E402


@pytest.fixture(scope="session")
def kemar() -> HRTF:
    return HRTF.load("kemar")


@pytest.fixture(scope="session")
def spherical() -> HRTF:
    return HRTF.spherical_head()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture(scope="session", autouse=True)
def model_cache(tmp_path_factory):
    """Trained models go to a fresh folder per test session (CI starts without a cache; a
    developer's own cache is never read or overwritten by the tests). A developer rerunning
    a few tests may set ACOUSTIC_SIM_TEST_CACHE to a folder kept between sessions (the
    models are trained into it once); CI never sets it."""
    import os

    kept = os.environ.get("ACOUSTIC_SIM_TEST_CACHE")
    path = Path(kept) if kept else tmp_path_factory.mktemp("model-cache")
    old = os.environ.get("ACOUSTIC_SIM_CACHE")
    os.environ["ACOUSTIC_SIM_CACHE"] = str(path)
    yield path
    if old is None:
        os.environ.pop("ACOUSTIC_SIM_CACHE", None)
    else:
        os.environ["ACOUSTIC_SIM_CACHE"] = old
