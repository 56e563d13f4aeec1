"""Ear front end (clock, window, FFT) and the paper's features (ILD/IPD, log-mel)."""

import numpy as np
import pytest

from acoustic_sim.auditory.features import (
    MEL_FRAMES,
    N_MELS,
    MelHistory,
    ear_volume,
    ild_ipd,
    log_mel_patches,
    mel_filterbank,
    normalize_log_mel,
)
from acoustic_sim.auditory.frontend import N_BINS, N_FFT, EarFrontEnd, analyze, bin_frequencies, frequency_to_bin, window
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample


def test_clock_over_an_hour_does_not_drift():
    """Frame k of an hour of audio ends exactly at round(k * 705.6); 225000 frames in 3600 s."""
    fe = EarFrontEnd()
    hour = 3600 * SAMPLE_RATE
    # Push an hour of (silent) samples in odd-sized blocks; only the clock is checked here.
    block = np.zeros((2, 44_099))
    last = None
    count = 0
    while fe.sample + block.shape[1] <= hour:
        f = fe.push(block)
        count += len(f)
        if len(f):
            last = f
    f = fe.push(np.zeros((2, hour - fe.sample)))
    count += len(f)
    last = f if len(f) else last
    assert count == 225_000
    assert last.index[-1] == 225_000
    assert last.time_s[-1] == pytest.approx(3600.0, abs=1e-12)
    assert frame_end_sample(225_000) == hour
    gaps = np.diff(frame_end_sample(np.arange(0, 225_001)))
    assert set(np.unique(gaps)) == {705, 706}


def test_streaming_equals_whole_recording_bit_for_bit(rng):
    x = rng.standard_normal((2, 30_000))
    whole = analyze(x)
    fe = EarFrontEnd()
    parts, i = [], 0
    for n in [1, 704, 705, 706, 2500, 3, 9000]:
        parts.append(fe.push(x[:, i : i + n]))
        i += n
    parts.append(fe.push(x[:, i:]))
    spectra = np.concatenate([p.spectra for p in parts])
    index = np.concatenate([p.index for p in parts])
    np.testing.assert_array_equal(index, whole.index)
    np.testing.assert_array_equal(spectra, whole.spectra)
    assert whole.spectra.shape == (len(whole), 2, N_BINS)


def test_frame_is_the_hamming_windowed_fft_of_the_last_2048_samples(rng):
    x = rng.standard_normal((2, 10_000))
    f = analyze(x)
    k = 7
    end = frame_end_sample(k)
    expected = np.fft.rfft(x[:, end - N_FFT : end] * window(), axis=-1)
    np.testing.assert_allclose(f.spectra[k - 1], expected, rtol=1e-5, atol=1e-4)
    assert f.time_s[k - 1] == end / SAMPLE_RATE
    # A sine peaks in its own bin.
    tone = np.sin(2 * np.pi * 1000.0 * np.arange(10_000) / SAMPLE_RATE)
    g = analyze(np.stack([tone, tone]))
    assert np.argmax(np.abs(g.spectra[-1, 0])) == frequency_to_bin(1000.0)


def test_front_end_rejects_bad_input():
    with pytest.raises(ConfigError, match=r"shape \(2, n\)"):
        analyze(np.zeros(100))
    with pytest.raises(ConfigError, match="NaN"):
        EarFrontEnd().push(np.full((2, 10), np.nan))
    with pytest.raises(ConfigError, match="within"):
        frequency_to_bin(30_000.0)
    assert analyze(np.zeros((2, 100))).spectra.shape == (0, 2, N_BINS)
    assert bin_frequencies()[-1] == SAMPLE_RATE / 2


def test_ild_ipd_follow_the_paper():
    xl = np.array([2.0 * np.exp(1j * 0.3), 1.0 + 0j])
    xr = np.array([0.5 * np.exp(-1j * 1.2), 1.0j])
    f = ild_ipd(xl, xr)
    norm = np.sqrt(np.abs(xl) ** 2 + np.abs(xr) ** 2)
    hat_l, hat_r = xl / norm, xr / norm
    np.testing.assert_allclose(f[:, 0], np.log(np.abs(hat_l)) - np.log(np.abs(hat_r)), rtol=1e-6)
    np.testing.assert_allclose(f[:, 1] + 1j * f[:, 2], hat_l / np.abs(hat_l), rtol=1e-6)
    np.testing.assert_allclose(f[:, 3] + 1j * f[:, 4], hat_r / np.abs(hat_r), rtol=1e-6)
    assert f[0, 0] == pytest.approx(np.log(4.0), rel=1e-6)
    # Level invariance: scaling both ears changes nothing.
    np.testing.assert_allclose(ild_ipd(7.0 * xl, 7.0 * xr), f, rtol=1e-5, atol=1e-6)


def test_features_on_silence_are_finite():
    z = np.zeros((3, N_BINS), np.complex64)
    f = ild_ipd(z, z)
    assert np.all(np.isfinite(f))
    np.testing.assert_array_equal(f[..., 0], 0.0)
    # One ear silent, the other loud: ILD is large but finite.
    one = ild_ipd(np.ones(4), np.zeros(4))
    assert np.all(np.isfinite(one)) and np.all(one[:, 0] > 20)
    patches = log_mel_patches(np.zeros((5, 2, N_BINS), np.complex64))
    assert patches.shape == (5, 2, MEL_FRAMES, N_MELS)
    np.testing.assert_array_equal(patches, -1.0)
    with pytest.raises(ConfigError, match="same shape"):
        ild_ipd(np.ones(3), np.ones(4))


def test_log_mel_is_relative_and_streams(rng):
    x = rng.standard_normal((2, 40_000))
    f = analyze(x)
    p = log_mel_patches(f.spectra)
    assert p.shape == (len(f), 2, MEL_FRAMES, N_MELS)
    assert p.min() >= -1.0 and p.max() == 0.0
    # Relative intensity: 20 dB louder gives the same input.
    np.testing.assert_allclose(log_mel_patches(10.0 * f.spectra), p, atol=1e-5)
    hist = MelHistory()
    for k in range(40):
        hist.push(f.spectra[k])
    np.testing.assert_array_equal(hist.patch(), p[39])
    bank = mel_filterbank()
    assert bank.shape == (N_MELS, N_BINS)
    assert np.all(bank.sum(axis=1) > 0.999) and np.all((bank > 0).sum(axis=1) >= 1)
    assert normalize_log_mel(np.ones((MEL_FRAMES, N_MELS))).max() == 0.0


def test_ear_volume_is_mean_power():
    x = np.array([[3.0, 4.0j], [0.0, 0.0]])
    np.testing.assert_allclose(ear_volume(x), [12.5, 0.0])
