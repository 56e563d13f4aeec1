"""The paper's test signals and recorded sound files.

The direction-estimation experiment uses sine, triangle, square and sawtooth waves (500,
1000, 2000 Hz) and white noise: :func:`test_signal` makes them band-limited (a sum of the
harmonics below Nyquist with their Fourier amplitudes), phase 0 and deterministic.
:func:`load_wav` reads recordings at the project's rate and keeps their recorded scale.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import soundfile as sf
from scipy import signal

from acoustic_sim.acoustics.sounds.sound_checks import check_rate, check_rng, finite_number, normalized, num_samples
from acoustic_sim.errors import SoundError
from acoustic_sim.frames import SAMPLE_RATE

TEST_WAVEFORMS: tuple[str, ...] = ("sine", "triangle", "square", "sawtooth")
"""Periodic test waveforms of the paper's direction-estimation experiment."""


def test_signal(waveform: str, f0_hz: float, seconds: float, *, sample_rate: int = SAMPLE_RATE,
                rng: np.random.Generator | None = None) -> np.ndarray:
    """A band-limited periodic test waveform (or white noise), as in the paper.

    Parameters
    ----------
    waveform : str
        One of :data:`TEST_WAVEFORMS` or ``"white_noise"``.
    f0_hz : float
        Fundamental frequency in Hz, 0 < f0 < sample_rate / 2; ignored for white noise.
    seconds : float
        Length in s, in (0, 600].
    sample_rate : int, optional
        Sample rate in Hz, 8000-384000 (default 44100).
    rng : numpy.random.Generator or None, optional
        Required for ``"white_noise"``; the periodic waveforms use none (phase 0).

    Returns
    -------
    numpy.ndarray, shape (round(seconds * sample_rate),), float64
        RMS 1.0. Only harmonics strictly below Nyquist are present, with the Fourier
        amplitudes of the ideal waveform: square 1/n (odd n), triangle 1/n^2 (odd n,
        alternating sign), sawtooth 1/n (all n).

    Raises
    ------
    SoundError
        Unknown waveform, f0 out of range, bad ``seconds``, or white noise without ``rng``.
    """
    sr = check_rate(sample_rate)
    if waveform == "white_noise":
        if rng is None:
            raise SoundError("test_signal('white_noise', ...) needs rng=numpy.random.Generator")
        return white_noise(seconds, rng, sample_rate=sr)
    if not isinstance(waveform, str) or waveform not in TEST_WAVEFORMS:
        raise SoundError(f"unknown test waveform {waveform!r}; valid: "
                         f"{', '.join(TEST_WAVEFORMS + ('white_noise',))}")
    f0 = finite_number(f0_hz, "f0_hz")
    if not 0.0 < f0 < sr / 2:
        raise SoundError(f"f0_hz must be in (0, {sr / 2:g}) Hz (Nyquist), got {f0_hz!r}")
    n = num_samples(seconds, sr)
    # Wrapping the phase to one cycle keeps h * theta accurate for long signals.
    theta = 2 * np.pi * np.mod(f0 * np.arange(n) / sr, 1.0)
    x = np.zeros(n)
    for h in range(1, int(np.ceil(sr / 2 / f0))):
        if h * f0 >= sr / 2:
            break
        amp = _harmonic_amplitude(waveform, h)
        if amp:
            x += amp * np.sin(h * theta)
    return normalized(x, f"{waveform} at {f0:g} Hz ({n} samples)")


def white_noise(seconds: float, rng: np.random.Generator, *,
                sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Gaussian white noise, flat up to Nyquist.

    Parameters
    ----------
    seconds : float
        Length in s, in (0, 600].
    rng : numpy.random.Generator
        Source of the samples.
    sample_rate : int, optional
        Sample rate in Hz, 8000-384000 (default 44100).

    Returns
    -------
    numpy.ndarray, shape (round(seconds * sample_rate),), float64
        RMS exactly 1.0.
    """
    sr = check_rate(sample_rate)
    check_rng(rng)
    n = num_samples(seconds, sr)
    return normalized(rng.standard_normal(n), "white noise")



def load_wav(path, *, sample_rate: int = SAMPLE_RATE, mono: bool = True) -> np.ndarray:
    """Read a sound file (any format libsndfile reads) at the project's sample rate.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    sample_rate : int, optional
        Target rate in Hz, 8000-384000 (default 44100). Other rates are resampled with a
        polyphase filter at the exact rational factor.
    mono : bool, optional
        Average the channels into one (default True).

    Returns
    -------
    numpy.ndarray, float64
        Shape (n,) if ``mono`` else (n, channels); the recorded scale, not normalized.

    Raises
    ------
    SoundError
        The file is missing, not a sound file, empty, or holds NaN/inf samples.
    """
    sr = check_rate(sample_rate)
    try:
        p = Path(path)
    except TypeError:
        raise SoundError(f"path must be a str or os.PathLike, got {type(path).__name__}") from None
    if not p.exists():
        raise SoundError(f"{p}: no such file")
    if not p.is_file():
        raise SoundError(f"{p}: not a regular file")
    try:
        data, file_sr = sf.read(p, dtype="float64", always_2d=True)
    except (sf.SoundFileError, RuntimeError, OSError, ValueError) as exc:
        raise SoundError(f"{p}: not a readable sound file ({exc})") from exc
    if data.size == 0:
        raise SoundError(f"{p}: contains no samples")
    bad = int(np.count_nonzero(~np.isfinite(data)))
    if bad:
        raise SoundError(f"{p}: {bad} NaN or infinite samples")
    ratio = Fraction(sr, int(file_sr))
    if ratio != 1:
        data = signal.resample_poly(data, ratio.numerator, ratio.denominator, axis=0)
    out = data.mean(axis=1) if mono else data
    return np.ascontiguousarray(out, dtype=np.float64)



def _harmonic_amplitude(waveform: str, h: int) -> float:
    # Fourier series of the ideal waveforms, overall scale irrelevant (normalized later).
    if waveform == "sine":
        return 1.0 if h == 1 else 0.0
    if waveform == "square":
        return 1.0 / h if h % 2 else 0.0
    if waveform == "triangle":
        return (-1.0) ** ((h - 1) // 2) / h**2 if h % 2 else 0.0
    return (-1.0) ** (h + 1) / h  # sawtooth

