"""The paper's HRTF measurement, simulated: the result is the HRTF plus the room."""

import numpy as np
import pytest

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.measure import measure_hrtf
from acoustic_sim.errors import ConfigError


def test_measured_hrtf_reproduces_the_ears_it_measured(tmp_path, kemar):
    out = tmp_path / "measured.sofa"
    info = measure_hrtf(hrtf=kemar, room="conference", distance_m=1.5, seconds=0.6, max_directions=6, out=out, progress=False)
    assert info["directions"] == 6
    measured = HRTF.load(out)
    assert measured.n_directions == 6 and measured.sample_rate == 44100
    for i in range(measured.n_directions):
        true = kemar.hrir[kemar.nearest_index(measured.directions[i : i + 1])[0]]
        got = measured.hrir[i]
        # Interaural level difference within 1.5 dB (the room's early reflections differ).
        ild = lambda h: 10 * np.log10(np.sum(h[0] ** 2) / np.sum(h[1] ** 2))  # noqa: E731
        assert abs(ild(got) - ild(true)) < 1.5
        # The direct sound's waveform: normalized cross-correlation of the first 150
        # samples of the left ear at the best lag >= 0.85 (the late tail and the noises leak
        # into a 0.6 s estimate).
        n = 150
        ncc = max(
            np.dot(got[0, s : s + n], true[0, :n]) / np.linalg.norm(got[0, s : s + n]) / np.linalg.norm(true[0, :n])
            for s in range(60)
        )
        assert ncc >= 0.85


def test_measure_errors(tmp_path):
    with pytest.raises(ConfigError, match=".sofa"):
        measure_hrtf(out=tmp_path / "x.wav", progress=False)
    with pytest.raises(ConfigError, match="distance"):
        measure_hrtf(distance_m=10.0, out=tmp_path / "x.sofa", progress=False)
