"""The ear unit's front end: framing, Hamming window and rFFT on the 62.5 Hz sample clock.

The paper's acoustic processing board (its eq. for X_{l,r}(t, w)) windows the last N = 2048
samples of each ear with a Hamming window and transmits the FFT every 1/62.5 s. Here ear
frame ``k`` (k = 1, 2, ...) is the 2048 samples that end at sample
``frames.frame_end_sample(k)`` (exclusive), so frames are 705 or 706 samples apart and the
clock is exact over any length of audio. Samples before the start of the recording are
zeros (the first frames are partly silent, as on the real board after power-up).

Inputs are in the scale the microphone model (and the WAVs that ``render`` writes) uses:
digital full scale, 1.0 = :data:`acoustic_sim.acoustics.microphone.FULL_SCALE_PA` pascal.
Spectra are not rescaled; features downstream are level-invariant or normalised.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy import fft as sp_fft
from scipy import signal as sp_signal

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE, frame_end_sample

N_FFT = 2048
"""FFT points (and window length) of the ear unit."""

N_BINS = N_FFT // 2 + 1
"""Frequency bins per ear: 1025, bin i at i * 44100 / 2048 Hz (21.53 Hz apart)."""

MAX_ABS_SAMPLE = 1e6
"""Largest magnitude a sample may have, in full-scale units (the ADC clips at 1.0). Far
beyond it the float32 spectra and the power sums downstream overflow to inf, so a larger
block is refused before it enters any state."""


def bin_frequencies(n_fft: int = N_FFT, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Centre frequency (Hz) of every rFFT bin, shape (n_fft // 2 + 1,)."""
    return np.fft.rfftfreq(n_fft, 1.0 / sample_rate)


def frequency_to_bin(freq_hz, n_fft: int = N_FFT, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Nearest rFFT bin of a frequency (Hz); raises ConfigError outside 0..fs/2."""
    f = np.asarray(freq_hz, dtype=float)
    if np.any(~np.isfinite(f)) or np.any(f < 0) or np.any(f > sample_rate / 2):
        raise ConfigError(f"frequencies must be within 0..{sample_rate / 2} Hz, got {freq_hz}")
    return np.rint(f * n_fft / sample_rate).astype(np.int64)


def window(n_fft: int = N_FFT) -> np.ndarray:
    """The Hamming window (periodic, as for spectral analysis), float64 (n_fft,)."""
    return sp_signal.get_window("hamming", n_fft, fftbins=True)


def leakage_envelope(n_fft: int = N_FFT, *, main_lobe: int = 2, oversample: int = 64) -> np.ndarray:
    """How much power the window's sidelobes can put ``m`` bins away from a component's peak bin.

    Entry ``m`` (0 .. n_fft // 2) is the largest power ratio, over every position of a pure
    tone between bins, of the window's response ``m`` bins from the tone's strongest bin to
    that strongest bin; made non-increasing in ``m`` (an envelope), and 0 within
    ``main_lobe`` bins (the component's own main lobe is not leakage). For the Hamming window:
    -41 dB 3-5 bins away, -52 dB 23 bins away (500 Hz from a 1 kHz tone), -65 dB at 100
    bins, -81 dB at 1000 (the worst case includes the 1.75 dB scalloping loss).

    Parameters
    ----------
    n_fft : int
        Window length and FFT points.
    main_lobe : int
        Half-width of the main lobe in bins (Hamming: 2), >= 0.
    oversample : int
        Zero-padding factor of the window's spectrum (the resolution of tone positions), >= 1.

    Returns
    -------
    numpy.ndarray
        float64 (n_fft // 2 + 1,), power ratios in [0, 1].
    """
    if not (isinstance(main_lobe, (int, np.integer)) and main_lobe >= 0):
        raise ConfigError(f"main_lobe must be an integer >= 0, got {main_lobe!r}")
    if not (isinstance(oversample, (int, np.integer)) and oversample >= 1):
        raise ConfigError(f"oversample must be an integer >= 1, got {oversample!r}")
    return _leakage_envelope(int(n_fft), int(main_lobe), int(oversample)).copy()


@functools.lru_cache(maxsize=4)
def _leakage_envelope(n_fft: int, main_lobe: int, oversample: int) -> np.ndarray:
    response = np.abs(np.fft.rfft(window(n_fft), n_fft * oversample)) ** 2  # at offsets of 1/oversample bin
    n = n_fft // 2 + 1
    # A tone delta bins (|delta| <= 1/2) above its strongest bin puts W(m - delta) at m bins,
    # and W(delta) at the strongest bin: the worst case over delta.
    half = oversample // 2
    peak_min = response[: half + 1].min()
    padded = np.concatenate([response, np.zeros(half + 1)])
    offsets = np.arange(n)[:, None] * oversample + np.arange(-half, half + 1)[None, :]
    worst = padded[np.abs(offsets)].max(axis=1) / peak_min
    env = np.maximum.accumulate(worst[::-1])[::-1]  # non-increasing: an envelope
    env[: main_lobe + 1] = 0.0
    env.setflags(write=False)
    return env


@dataclass(frozen=True)
class Frames:
    """Spectra of consecutive ear frames.

    Attributes
    ----------
    index : numpy.ndarray
        Frame numbers k (int64, shape (K,)); frame k ends at ``frame_end_sample(k)``.
    time_s : numpy.ndarray
        End time of each frame in seconds (float64, shape (K,)): the frame's time stamp.
    spectra : numpy.ndarray
        complex64 (K, 2, N_BINS): left and right rFFT of the windowed frame.
    """

    index: np.ndarray
    time_s: np.ndarray
    spectra: np.ndarray

    def __len__(self) -> int:
        return int(self.index.size)


def _check_audio(audio, what: str = "audio") -> np.ndarray:
    x = np.asarray(audio)
    if x.ndim != 2 or x.shape[0] != 2:
        raise ConfigError(f"{what} must have shape (2, n) (left, right), got {x.shape}")
    if not np.issubdtype(x.dtype, np.floating) and not np.issubdtype(x.dtype, np.integer):
        raise ConfigError(f"{what} must be real numbers, got dtype {x.dtype}")
    x = x.astype(np.float64, copy=False)
    if not np.all(np.isfinite(x)):
        raise ConfigError(f"{what} contains NaN or inf samples")
    peak = float(np.max(np.abs(x), initial=0.0))
    if peak > MAX_ABS_SAMPLE:
        raise ConfigError(f"{what} has a sample of magnitude {peak:.3g}, beyond {MAX_ABS_SAMPLE:.0e} full scale "
                          "(digital ear samples, 1.0 = the ADC's full scale)")
    return x


def _fft_frames(segments: np.ndarray, win: np.ndarray) -> np.ndarray:
    """rFFT of windowed segments (..., n_fft) -> complex64 (..., n_fft // 2 + 1)."""
    return sp_fft.rfft(segments * win, axis=-1).astype(np.complex64)


def analyze(audio, *, sample_rate: int = SAMPLE_RATE, frame_rate: float = FRAME_RATE, n_fft: int = N_FFT) -> Frames:
    """Spectra of every complete ear frame of a whole recording.

    Parameters
    ----------
    audio : array_like, shape (2, n)
        Left and right samples at ``sample_rate`` Hz (full-scale units).
    sample_rate : int
        Hz.
    frame_rate : float
        Frames per second (the paper: 62.5).
    n_fft : int
        Window and FFT length in samples.

    Returns
    -------
    Frames
        Frames k = 1 .. K with ``frame_end_sample(K) <= n``.
    """
    x = _check_audio(audio)
    n = x.shape[1]
    # The last frame ending within the recording (a short search from the estimate).
    k_last = max(int(np.floor(n * frame_rate / sample_rate)) + 1, 0)
    while k_last > 0 and frame_end_sample(k_last, sample_rate, frame_rate) > n:
        k_last -= 1
    index = np.arange(1, k_last + 1, dtype=np.int64)
    if index.size == 0:
        return Frames(index, np.zeros(0), np.zeros((0, 2, n_fft // 2 + 1), np.complex64))
    ends = np.asarray(frame_end_sample(index, sample_rate, frame_rate), dtype=np.int64)
    padded = np.concatenate([np.zeros((2, n_fft)), x], axis=1)
    # Frame k covers samples [end - n_fft, end), i.e. padded[end : end + n_fft].
    view = np.lib.stride_tricks.sliding_window_view(padded, n_fft, axis=1)  # (2, n + 1, n_fft)
    segments = view[:, ends, :].transpose(1, 0, 2)  # (K, 2, n_fft)
    spectra = _fft_frames(segments, window(n_fft))
    return Frames(index, ends / sample_rate, spectra)


class EarFrontEnd:
    """Streaming front end: push audio blocks of any length, get the frames they complete.

    Parameters
    ----------
    sample_rate : int
        Hz.
    frame_rate : float
        Frames per second.
    n_fft : int
        Window and FFT length (samples).

    Notes
    -----
    Pushing a recording in blocks of any sizes gives exactly the frames (bit for bit) that
    :func:`analyze` gives for the whole recording.
    """

    def __init__(self, *, sample_rate: int = SAMPLE_RATE, frame_rate: float = FRAME_RATE, n_fft: int = N_FFT) -> None:
        if n_fft < 16 or n_fft % 2:
            raise ConfigError(f"n_fft must be an even number >= 16, got {n_fft}")
        self.sample_rate = sample_rate
        self.frame_rate = frame_rate
        self.n_fft = n_fft
        self.window = window(n_fft)
        self.buffer = np.zeros((2, n_fft))  # the last n_fft samples
        self.sample = 0  # samples pushed so far (the clock)
        self.next_frame = 1

    def reset(self) -> None:
        """Back to sample 0 with an empty (silent) buffer."""
        self.buffer[:] = 0.0
        self.sample = 0
        self.next_frame = 1

    def push(self, block) -> Frames:
        """Append a (2, n) block; returns the frames whose last sample it contains."""
        x = _check_audio(block, "block")
        n = x.shape[1]
        end = self.sample + n
        ends, index = [], []
        k = self.next_frame
        while (e := frame_end_sample(k, self.sample_rate, self.frame_rate)) <= end:
            ends.append(e)
            index.append(k)
            k += 1
        joined = np.concatenate([self.buffer, x], axis=1)  # covers samples [sample - n_fft, end)
        if ends:
            offsets = np.asarray(ends) - (self.sample - self.n_fft)
            segments = np.stack([joined[:, o - self.n_fft : o] for o in offsets])
            spectra = _fft_frames(segments, self.window)
        else:
            spectra = np.zeros((0, 2, self.n_fft // 2 + 1), np.complex64)
        self.buffer = joined[:, -self.n_fft :].copy()
        self.sample = end
        self.next_frame = k
        idx = np.asarray(index, dtype=np.int64)
        return Frames(idx, np.asarray(ends, dtype=float) / self.sample_rate, spectra)
