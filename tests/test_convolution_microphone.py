"""Streaming kernels and the microphone/ADC model."""

import numpy as np
import pytest

from acoustic_sim.acoustics import convolution
from acoustic_sim.acoustics.convolution import FrameConvolver, PartitionedConvolver, assemble, fractional_hrir_table
from acoustic_sim.acoustics.microphone import FULL_SCALE_PA, Microphone, MicrophoneSpec, a_weighting_power_gain
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample


def test_partitioned_convolver_equals_direct_convolution_for_clock_blocks():
    rng = np.random.default_rng(0)
    h = rng.standard_normal((2, 6000))
    h[:, :512] = 0.0
    x = rng.standard_normal(40000)
    conv = PartitionedConvolver(h, 512)
    blocks, start = [], 0
    for length in [705, 706] * 20 + [1, 3, 4096]:
        blocks.append(conv.process(x[start : start + length]))
        start += length
    y = np.concatenate(blocks, axis=1)
    ref = np.stack([np.convolve(x[:start], h[e])[:start] for e in range(2)])
    assert np.max(np.abs(y - ref)) < 1e-5 * np.max(np.abs(ref))  # float32 spectra


def test_partitioned_convolver_refuses_a_filter_that_needs_latency():
    with pytest.raises(ValueError, match="first partition"):
        PartitionedConvolver(np.ones((1, 100)), 64)


def test_fractional_table_shifts_by_the_fraction():
    """Row q is the HRIR delayed by q/Q of a sample: a linear phase of that slope."""
    t = np.arange(128)
    pulse = np.sinc(0.8 * (t - 64.0)) * np.hanning(128)  # band-limited, well inside the response
    table = fractional_hrir_table(np.stack([pulse, -pulse])[None], 8)
    freqs = np.fft.rfftfreq(512)
    band = (freqs > 0.01) & (freqs < 0.3)
    ref = np.fft.rfft(table[0, 0, 0::2], 512)
    for q in range(1, 8):
        ratio = np.fft.rfft(table[0, q, 0::2], 512)[band] / ref[band]
        np.testing.assert_allclose(ratio, np.exp(-2j * np.pi * freqs[band] * q / 8), atol=2e-3)
    np.testing.assert_allclose(table[0, 3, 1::2], -table[0, 3, 0::2])  # right ear interleaved


def test_assemble_places_rows_and_sums_weight_sets():
    rows = np.array([[1.0, 10.0, 2.0, 20.0], [3.0, 30.0, 4.0, 40.0]], dtype=np.float32)  # 2 rows, T=2 stereo
    out = assemble(rows, np.array([0, 1]), 4)
    np.testing.assert_allclose(out, [[1.0, 5.0, 4.0, 0.0], [10.0, 50.0, 40.0, 0.0]])
    two = assemble(rows, np.array([0, 1]), 4, np.array([[1.0, 0.0], [0.0, 2.0]]))
    np.testing.assert_allclose(two[1], [[0.0, 6.0, 8.0, 0.0], [0.0, 60.0, 80.0, 0.0]])


def test_microphone_full_scale_noise_and_clipping():
    mic = Microphone(rng=np.random.default_rng(0))
    # Full scale is the peak of a 132 dB SPL sine: 112.5 Pa.
    assert abs(FULL_SCALE_PA - 20e-6 * 10 ** (132 / 20) * np.sqrt(2)) < 1e-9
    t = np.arange(SAMPLE_RATE) / SAMPLE_RATE
    tone = 20e-6 * 10 ** (94 / 20) * np.sqrt(2) * np.sin(2 * np.pi * 1000 * t)  # 94 dB SPL, 1 Pa RMS
    y = mic(np.stack([tone, tone])).astype(float)
    level = 20 * np.log10(np.std(y[0, 4410:]) * FULL_SCALE_PA / 20e-6)
    assert abs(level - 94.0) < 0.05
    # Self-noise: 94 dB - 67 dB SNR = 27 dBA; white noise reads higher unweighted.
    quiet = Microphone(rng=np.random.default_rng(1))(np.zeros((2, SAMPLE_RATE))).astype(float)
    noise_dba = 20 * np.log10(np.std(quiet[:, 4410:]) * FULL_SCALE_PA * np.sqrt(a_weighting_power_gain()) / 20e-6)
    assert abs(noise_dba - 27.0) < 0.3
    # Overload: a 140 dB SPL burst clips at full scale, never beyond.
    loud = mic(np.full((2, 100), 20e-6 * 10 ** (140 / 20) * 2))
    assert loud.max() <= 1.0 and loud.max() > 0.999
    # 24-bit: every sample is a multiple of 2**-23.
    assert np.all(np.round(y * 2**23) == y * 2**23)


def test_microphone_errors():
    mic = Microphone(rng=np.random.default_rng(0))
    with pytest.raises(ConfigError, match="shape"):
        mic(np.zeros(10))
    with pytest.raises(ConfigError, match="NaN"):
        mic(np.full((2, 4), np.nan))
    with pytest.raises(ConfigError, match="snr"):
        MicrophoneSpec(snr_dba=-3)


def test_assemble_is_the_sum_of_shifted_rows():
    rng = np.random.default_rng(2)
    rows = rng.standard_normal((40, 2 * 65)).astype(np.float32)
    offsets = rng.integers(0, 900, 40)
    weights = rng.standard_normal((3, 40))
    out = assemble(rows, offsets, 1024, weights)
    ref = np.zeros((3, 2, 1024))
    for m in range(40):
        ref[:, :, offsets[m] : offsets[m] + 65] += weights[:, m, None, None] * rows[m].reshape(65, 2).T[None]
    np.testing.assert_allclose(out, ref, atol=1e-5)


def test_frame_convolver_equals_direct_convolution_over_clock_frames():
    """Partitions are the 705/706-sample frames of the project clock; changing the FFT
    size mid-stream re-transforms the kept input without a seam."""
    from scipy.signal import fftconvolve

    rng = np.random.default_rng(3)
    h = rng.standard_normal((2, 9000))
    h[:, :1024] = 0.0
    x = rng.standard_normal(40000)
    ref = fftconvolve(x[None, :], h, axes=-1)[:, : x.size]
    conv = FrameConvolver(h)
    conv.set_fft_size(2048)
    ends = [int(frame_end_sample(k)) for k in range(57)]
    blocks = []
    for k in range(1, 57):
        if k == 30:
            conv.set_fft_size(3072)
        blocks.append(conv.process(x[ends[k - 1] : ends[k]]))
    y = np.concatenate(blocks, axis=1)
    assert np.max(np.abs(y - ref[:, : y.shape[1]])) < 1e-5 * np.max(np.abs(ref))
    assert len(conv._stacks) <= 5  # the clock's frame pattern repeats every 5 frames


def test_frame_convolver_refuses_frames_it_cannot_render_exactly():
    h = np.zeros((1, 5000))
    h[0, 600:] = 1.0
    conv = FrameConvolver(h)
    conv.set_fft_size(2048)
    conv.process(np.ones(500))
    with pytest.raises(ValueError, match="first 705 taps"):
        conv.process(np.ones(705))  # the filter starts at 600: the frame would need itself
    wide = FrameConvolver(np.pad(np.ones((1, 100)), ((0, 0), (1500, 0))))
    wide.set_fft_size(2048)
    wide.process(np.ones(1400))
    with pytest.raises(ValueError, match="windows of"):
        wide.process(np.ones(1400))  # 1400 + 1400 - 1 > 2048


@pytest.mark.parametrize("direct", [True, False])
def test_fft_helpers_match_scipy(monkeypatch, direct):
    """The renderer's transforms (pocketfft called directly when SciPy has it, else
    scipy.fft) give scipy.fft's results, for the strided float32 views it passes."""
    import scipy.fft as sfft

    if not direct:
        monkeypatch.setattr(convolution, "_POCKETFFT", None)
    rng = np.random.default_rng(4)
    buf = rng.standard_normal((3, 5000)).astype(np.float32)
    x = buf[:, 1000:3048]
    np.testing.assert_allclose(convolution.rfft(x), sfft.rfft(x, axis=-1), atol=1e-3)
    assert convolution.rfft(x).dtype == np.complex64
    spec = sfft.rfft(rng.standard_normal((2, 2, 2048)).astype(np.float32), axis=-1)
    np.testing.assert_allclose(convolution.irfft(spec, 2048), sfft.irfft(spec, n=2048, axis=-1), atol=1e-5)


def test_microphone_fast_filter_path_equals_lfilter(monkeypatch):
    """The microphone calls lfilter's compiled kernel directly when SciPy has it; the
    public lfilter gives the same samples."""
    from acoustic_sim.acoustics import microphone

    p = np.random.default_rng(2).standard_normal((2, 3000)) * 0.5
    fast = Microphone(rng=np.random.default_rng(9))
    a = np.concatenate([fast(p[:, i : i + 705]) for i in range(0, 3000, 705)], axis=1)
    monkeypatch.setattr(microphone, "_LINEAR_FILTER", None)
    slow = Microphone(rng=np.random.default_rng(9))
    b = np.concatenate([slow(p[:, i : i + 705]) for i in range(0, 3000, 705)], axis=1)
    np.testing.assert_array_equal(a, b)
