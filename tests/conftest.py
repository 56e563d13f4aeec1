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
    worker = os.environ.get("PYTEST_XDIST_WORKER")  # `pytest -n N` (make test): one cache for the run
    if kept:
        path = Path(kept)
    elif worker:
        path = tmp_path_factory.getbasetemp().parent / "model-cache"
        path.mkdir(exist_ok=True)
    else:
        path = tmp_path_factory.mktemp("model-cache")
    old = os.environ.get("ACOUSTIC_SIM_CACHE")
    os.environ["ACOUSTIC_SIM_CACHE"] = str(path)
    if worker:
        # The fast models every task test needs, trained once for the run, not once per
        # worker (that would double the suite's longest part).
        from filelock import FileLock

        from acoustic_sim.auditory.melcnn import MelCNN
        from acoustic_sim.auditory.ssdenet import SSDENetBank
        from acoustic_sim.directions import DirectionGrid
        from tasks.auditory import load_hrtf

        def bank():
            ears = load_hrtf("kemar")
            SSDENetBank.load_or_train(ears, DirectionGrid.paper(ears), "fast", progress=False)

        def cnn():
            MelCNN.load_or_train("fast", progress=False)

        # Each model under its own lock, the workers taking them in opposite orders: the two
        # train at once, and every worker finds both in the cache afterwards.
        jobs = [("ssdenet", bank), ("melcnn", cnn)]
        if worker.removeprefix("gw").isdigit() and int(worker.removeprefix("gw")) % 2:
            jobs.reverse()
        for name, train in jobs:
            with FileLock(f"{path}.{name}.lock"):
                train()
    yield path
    if old is None:
        os.environ.pop("ACOUSTIC_SIM_CACHE", None)
    else:
        os.environ["ACOUSTIC_SIM_CACHE"] = old
