"""The paper's HRTF measurement, simulated: the result is the HRTF plus the room."""

import numpy as np
import pytest

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.measure import measure_hrtf
from acoustic_sim.errors import ConfigError


def broadband_ild_db(h) -> float:
    """Interaural level difference (dB) of a (2, n) impulse response over all frequencies."""
    return float(10 * np.log10(np.sum(h[0] ** 2) / np.sum(h[1] ** 2)))


def true_hrir(ears, measured, i):
    """The ears' own response nearest to the measured response ``i``'s direction."""
    return ears.hrir[ears.nearest_index(measured.directions[i : i + 1])[0]]


def test_measured_hrtf_reproduces_the_ears_it_measured(tmp_path, kemar):
    out = tmp_path / "measured.sofa"
    info = measure_hrtf(hrtf=kemar, room="conference", distance_m=1.5, seconds=0.6, max_directions=6, out=out, progress=False)
    assert info["directions"] == 6
    measured = HRTF.load(out)
    assert measured.n_directions == 6 and measured.sample_rate == 44100
    for i in range(measured.n_directions):
        true = true_hrir(kemar, measured, i)
        got = measured.hrir[i]
        # Interaural level difference within 2 dB: the conference room's reflections of the
        # first 11.6 ms (512 taps) are part of the measured response (0.1-1.5 dB here).
        assert abs(broadband_ild_db(got) - broadband_ild_db(true)) < 2.0
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


def test_a_short_measured_response_is_the_room_s_response_cut_there(tmp_path, kemar):
    """taps=128 (2.2 ms after the sound reaches the head centre): a gate that keeps the
    direct sound and drops the conference room's reflections, so the measured ILD per
    frequency follows the ears'. With Welch segments of 2 * taps (the first version) the
    estimate was smoothed over the room's reverberation instead: mean |ILD error| over
    0.5-12 kHz on these 6 directions 8.8 dB, against 1.7 dB with the 8192-sample segments."""
    out = tmp_path / "gated.sofa"
    measure_hrtf(hrtf=kemar, room="conference", distance_m=1.5, seconds=0.6, taps=128, max_directions=6, out=out,
                 progress=False)
    measured = HRTF.load(out)
    f = np.fft.rfftfreq(2048, 1 / 44100)
    band = (f > 500) & (f < 12000)

    def ild_db(h):
        spec = np.abs(np.fft.rfft(h, 2048, axis=-1)) + 1e-12
        return 20 * np.log10(spec[0] / spec[1])[band]

    errors = [np.mean(np.abs(ild_db(measured.hrir[i]) - ild_db(true_hrir(kemar, measured, i))))
              for i in range(measured.n_directions)]
    assert np.mean(errors) < 3.0, errors
    # Broadband, the gated response's ILD is within 1 dB of the ears' (0.1-0.7 dB here; with
    # the reflections of 512 taps up to 1.5 dB, the test above).
    for i in range(measured.n_directions):
        assert abs(broadband_ild_db(measured.hrir[i]) - broadband_ild_db(true_hrir(kemar, measured, i))) < 1.0
