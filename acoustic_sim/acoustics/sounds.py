"""Sound bank: the six environmental sound classes, the paper's test signals, WAV loading.

Every signal is a float64 mono 1-D array at ``sample_rate`` (Hz), scaled to an RMS of
exactly 1.0 over the whole returned signal, so that the renderer's level in dB SPL at 1 m is
the signal's equivalent continuous level. Loaded WAV files are the exception: they keep
their recorded scale. Randomness comes only from the ``numpy.random.Generator`` passed in:
the same seed gives the same samples, bit for bit (``human_voice`` speaks with the espeak-ng
library that the project's ``espeakng-loader`` dependency bundles, the same on every machine
that installs it; see :mod:`~acoustic_sim.acoustics.espeak`).

The classes are the ones the paper's MelCNN is trained on (car horn, alarm, ratchet,
gearshift, key turning, human voice). They are synthesized from small physical models, and
every instance draws its own pitch, rhythm, timbre and duration, so that a classifier has to
learn the class and not one waveform:

``car_horn``
    Two electromagnetic disc horns a minor or major third apart (low one 370-500 Hz),
    slightly off just intonation. Each diaphragm slams into its stop, modelled by a driven
    ``tanh`` (rendered 4x oversampled so the harmonics do not alias), and the trumpet adds
    a high-pass and a 1.5-2.8 kHz resonance. Fast attack; one long honk or 2-3 short ones.
``reverse_alarm``
    A piezo backup beeper: a 1000-1300 Hz tone with weak odd harmonics (a square wave
    smoothed by the transducer), gated at a 0.8-1.1 s period with a ~50 % duty cycle.
``ratchet``
    A parking-brake pull: 5-14 pawl clicks 35-130 ms apart, slowing as the cable tightens.
    Each click excites 3-5 metal modes at 2-8 kHz (ms decays) plus an impact-noise burst,
    sometimes with a pawl bounce; every click jitters its modes, level and timing.
``gearshift``
    One to three lever throws: band-passed friction noise while the lever slides, ending
    in a clunk (a damped 100-400 Hz body mode, two higher modes, an impact burst and a few
    rattle clicks).
``key_turning``
    A key ring jingling (each key a set of 3-10 kHz ringing modes, struck in clusters),
    optionally the key scraping into the lock, then the ignition lock's click and detent.
``human_voice``
    A short call ("Musashi, over here!") through :func:`speech`: the bundled ``espeak-ng``
    with a random voice, pitch and speed, or where its wheel does not exist a formant
    synthesizer (glottal pulses with jitter and a call intonation, cascaded formant
    resonators, noise bursts for consonants; see the private section of this module).

The paper's direction-estimation experiment uses sine, triangle, square and sawtooth waves
(500, 1000, 2000 Hz) and white noise: :func:`test_signal` makes them band-limited (a sum of
the harmonics below Nyquist with their Fourier amplitudes), phase 0 and deterministic.
"""

from __future__ import annotations

import math
import numbers
import warnings
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Callable

import numpy as np
import soundfile as sf
from scipy import signal

from acoustic_sim.acoustics import espeak
from acoustic_sim.errors import SoundError
from acoustic_sim.frames import SAMPLE_RATE

SOUND_CLASSES: tuple[str, ...] = (
    "car_horn", "reverse_alarm", "ratchet", "gearshift", "key_turning", "human_voice",
)
"""The environmental sound classes, in the order of the classifier's outputs."""

TEST_WAVEFORMS: tuple[str, ...] = ("sine", "triangle", "square", "sawtooth")
"""Periodic test waveforms of the paper's direction-estimation experiment."""

VOICE_TEXTS: tuple[str, ...] = (
    "Musashi!", "Over here!", "Musashi, over here!", "Hey, Musashi!", "Hello!",
)
"""Phrases that ``human_voice`` instances call out."""

MAX_SECONDS = 600.0
"""Longest signal any generator makes, in s (guards against multi-gigabyte requests)."""

_MIN_RATE, _MAX_RATE = 8000, 384000


# --------------------------------------------------------------------------- public API

def available_sounds() -> tuple[str, ...]:
    """Names accepted by :func:`generate`: the six classes plus ``"white_noise"``."""
    return SOUND_CLASSES + ("white_noise",)


def generate(name: str, rng: np.random.Generator, *, seconds: float | None = None,
             sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Synthesize one random instance of a sound class.

    Parameters
    ----------
    name : str
        One of :func:`available_sounds`.
    rng : numpy.random.Generator
        The only source of randomness; the same state gives the same samples.
    seconds : float or None, optional
        Length in s, in (0, 600]. ``None`` (default) gives one natural instance (a
        0.3-1.2 s honk, a few alarm beeps, one ratchet pull, one phrase, ...; 1 s of
        white noise). Otherwise the result has exactly ``round(seconds * sample_rate)``
        samples: the alarm keeps beeping, the other classes repeat their event (same
        horn, same ratchet, same speaker) with random pauses, and the end is trimmed with
        a 5 ms fade.
    sample_rate : int, optional
        Sample rate in Hz, 8000-384000 (default 44100). Modes above 0.45 of it are dropped.

    Returns
    -------
    numpy.ndarray, shape (n,), float64
        Mono signal with an RMS of 1.0.

    Raises
    ------
    SoundError
        Unknown name, bad ``seconds``/``sample_rate``/``rng``, or a request so short that
        it holds only silence.
    """
    sr = _check_rate(sample_rate)
    _check_rng(rng)
    if not isinstance(name, str) or name not in available_sounds():
        raise SoundError(f"unknown sound {name!r}; valid names: {', '.join(available_sounds())}")
    n = None if seconds is None else _num_samples(seconds, sr)
    if name == "white_noise":
        return white_noise(1.0 if seconds is None else seconds, rng, sample_rate=sr)
    x = _CLASS_MODELS[name](rng, sr, n)
    return _normalized(x, f"{name} ({len(x)} samples)")


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
    sr = _check_rate(sample_rate)
    if waveform == "white_noise":
        if rng is None:
            raise SoundError("test_signal('white_noise', ...) needs rng=numpy.random.Generator")
        return white_noise(seconds, rng, sample_rate=sr)
    if not isinstance(waveform, str) or waveform not in TEST_WAVEFORMS:
        raise SoundError(f"unknown test waveform {waveform!r}; valid: "
                         f"{', '.join(TEST_WAVEFORMS + ('white_noise',))}")
    f0 = _finite(f0_hz, "f0_hz")
    if not 0.0 < f0 < sr / 2:
        raise SoundError(f"f0_hz must be in (0, {sr / 2:g}) Hz (Nyquist), got {f0_hz!r}")
    n = _num_samples(seconds, sr)
    # Wrapping the phase to one cycle keeps h * theta accurate for long signals.
    theta = 2 * np.pi * np.mod(f0 * np.arange(n) / sr, 1.0)
    x = np.zeros(n)
    for h in range(1, int(np.ceil(sr / 2 / f0))):
        if h * f0 >= sr / 2:
            break
        amp = _harmonic_amplitude(waveform, h)
        if amp:
            x += amp * np.sin(h * theta)
    return _normalized(x, f"{waveform} at {f0:g} Hz ({n} samples)")


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
    sr = _check_rate(sample_rate)
    _check_rng(rng)
    n = _num_samples(seconds, sr)
    return _normalized(rng.standard_normal(n), "white noise")


def speech(text: str, rng: np.random.Generator, *, sample_rate: int = SAMPLE_RATE,
           engine: str = "auto") -> np.ndarray:
    """Speak a short phrase with a random speaker.

    Parameters
    ----------
    text : str
        The phrase, 1-500 characters. The formant engine speaks Latin letters only
        (spelling-based, no dictionary) and needs at least one.
    rng : numpy.random.Generator
        Draws the speaker (voice, pitch, speed; or f0, vocal-tract length, breathiness).
    sample_rate : int, optional
        Sample rate in Hz, 8000-384000 (default 44100).
    engine : {"auto", "espeak", "formant"}, optional
        ``"auto"`` (default) uses the bundled ``espeak-ng`` when installed and falls back to
        the formant synthesizer, with a ``RuntimeWarning``, if it fails; ``"espeak"``
        raises instead; ``"formant"`` never runs ``espeak-ng``.

    Returns
    -------
    numpy.ndarray, shape (n,), float64
        The phrase with leading and trailing silence trimmed, RMS 1.0.

    Raises
    ------
    SoundError
        Bad text or engine, ``engine="espeak"`` with espeak-ng missing or failing.
    """
    sr = _check_rate(sample_rate)
    _check_rng(rng)
    _check_text(text)
    if engine not in ("auto", "espeak", "formant"):
        raise SoundError(f"engine must be 'auto', 'espeak' or 'formant', got {engine!r}")
    speaker = _draw_speaker(rng, engine)
    x = _speak(text, speaker, rng, sr, strict=engine == "espeak")
    return _normalized(x, f"speech {text!r}")


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
    sr = _check_rate(sample_rate)
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


# --------------------------------------------------------------------------- validation

def _check_rate(sample_rate) -> int:
    if (isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, np.integer))
            or not _MIN_RATE <= sample_rate <= _MAX_RATE):
        raise SoundError(f"sample_rate must be an integer in [{_MIN_RATE}, {_MAX_RATE}] Hz, "
                         f"got {sample_rate!r}")
    return int(sample_rate)


def _check_rng(rng) -> None:
    if not isinstance(rng, np.random.Generator):
        raise SoundError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")


def _finite(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise SoundError(f"{what} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise SoundError(f"{what} must be finite, got {value!r}")
    return v


def _num_samples(seconds, sr: int) -> int:
    s = _finite(seconds, "seconds")
    if not 0.0 < s <= MAX_SECONDS:
        raise SoundError(f"seconds must be in (0, {MAX_SECONDS:g}] s, got {seconds!r}")
    n = round(s * sr)
    if n < 1:
        raise SoundError(f"seconds={seconds!r} is shorter than one sample at {sr} Hz")
    return n


def _check_text(text) -> None:
    if not isinstance(text, str) or not text.strip() or len(text) > 500:
        raise SoundError(f"text must be a non-blank str of at most 500 characters, got {text!r}")


def _normalized(x: np.ndarray, what: str) -> np.ndarray:
    rms = float(np.sqrt(np.mean(np.square(x))))
    if not math.isfinite(rms) or rms == 0.0:
        raise SoundError(f"{what} is silent (too short to hold any sound?)")
    return x / rms


def _harmonic_amplitude(waveform: str, h: int) -> float:
    # Fourier series of the ideal waveforms, overall scale irrelevant (normalized later).
    if waveform == "sine":
        return 1.0 if h == 1 else 0.0
    if waveform == "square":
        return 1.0 / h if h % 2 else 0.0
    if waveform == "triangle":
        return (-1.0) ** ((h - 1) // 2) / h**2 if h % 2 else 0.0
    return (-1.0) ** (h + 1) / h  # sawtooth


# --------------------------------------------------------------------------- building blocks

def _modes(n: int, sr: int, freqs, decays, amps, phases) -> np.ndarray:
    """Sum of exponentially decaying sinusoids: the ring of a struck object's modes."""
    freqs, decays, amps, phases = (np.atleast_1d(np.asarray(v, float))
                                   for v in (freqs, decays, amps, phases))
    keep = freqs < 0.45 * sr
    t = np.arange(n) / sr
    ring = (amps[keep, None] * np.exp(-t / decays[keep, None])
            * np.sin(2 * np.pi * freqs[keep, None] * t + phases[keep, None]))
    return ring.sum(axis=0)


def _band(lo: float, hi: float, sr: int) -> np.ndarray:
    """Second-order-section band-pass, its upper edge kept below Nyquist."""
    hi = min(hi, 0.45 * sr)
    return signal.butter(2, [min(lo, 0.5 * hi), hi], "bandpass", fs=sr, output="sos")


def _burst(n: int, sr: int, rng: np.random.Generator, decay_s: float, lo: float,
           hi: float) -> np.ndarray:
    """Band-passed, exponentially decaying noise: the broadband crack of an impact."""
    noise = rng.standard_normal(n) * np.exp(-np.arange(n) / (decay_s * sr))
    return signal.sosfilt(_band(lo, hi, sr), noise)


def _add(out: np.ndarray, x: np.ndarray, start: int) -> None:
    """Mix ``x`` into ``out`` from sample ``start`` on, dropping what falls off the end."""
    start = int(start)
    m = min(len(x), len(out) - start)
    if m > 0:
        out[start:start + m] += x[:m]


def _fit(x: np.ndarray, n: int, sr: int) -> np.ndarray:
    """Exactly ``n`` samples: pad with silence, or cut with a short fade (no click)."""
    if len(x) < n:
        return np.concatenate([x, np.zeros(n - len(x))])
    x = x[:n].copy()
    f = min(n, round(0.005 * sr))
    x[n - f:] *= np.cos(0.5 * np.pi * np.arange(1, f + 1) / (f + 1))
    return x


def _fill(event: Callable[[], np.ndarray], n: int, rng: np.random.Generator, sr: int,
          gap_s: tuple[float, float]) -> np.ndarray:
    """Repeat ``event()`` with random silent pauses until ``n`` samples are covered."""
    parts, total = [], 0
    while total < n:
        x = event()
        if not parts:  # start on the sound, so that even a short request is not silent
            x = _trim_silence(x, sr, pad_s=0.0)
        gap = np.zeros(round(rng.uniform(*gap_s) * sr))
        parts += [x, gap]
        total += len(x) + len(gap)
    return _fit(np.concatenate(parts), n, sr)


def _ramp_envelope(n: int, sr: int, attack_s: float, release_s: float) -> np.ndarray:
    t = np.arange(n) / sr
    rise = np.clip(t / attack_s, 0, 1)
    fall = np.clip((n / sr - t) / release_s, 0, 1)
    return np.sin(0.5 * np.pi * np.minimum(rise, fall)) ** 2


# --------------------------------------------------------------------------- class models

def _car_horn(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    f_low = rng.uniform(370, 500)
    # Horn pairs are tuned to a third; cheap ones are a little off, which adds beating.
    ratio = rng.choice([6 / 5, 5 / 4]) * rng.uniform(0.985, 1.015)
    level_high = rng.uniform(0.5, 1.0)
    drive = rng.uniform(2.5, 8.0)     # how hard the diaphragm hits its stop
    even = rng.uniform(0.1, 0.5)      # asymmetric travel -> even harmonics
    bell_hz, bell_gain = rng.uniform(1500, 2800), rng.uniform(0.5, 2.0)
    cutoff = rng.uniform(4000, 7000)
    os = 4                            # the clipper's harmonics must not alias
    fs = sr * os
    sos_hp = signal.butter(2, 250, "highpass", fs=fs, output="sos")
    sos_bell = signal.butter(1, [bell_hz / 1.3, bell_hz * 1.3], "bandpass", fs=fs, output="sos")
    sos_lp = signal.butter(4, min(cutoff, 0.45 * sr), "lowpass", fs=fs, output="sos")

    def honk(seconds: float) -> np.ndarray:
        m = round(seconds * sr) * os
        t = np.arange(m) / fs
        y = np.zeros(m)
        for f, level in ((f_low, 1.0), (f_low * ratio, level_high)):
            # Pitch settles while the diaphragm builds up; slow wander from supply voltage.
            knots = rng.normal(0, 0.002, int(seconds * 20) + 2)
            wander = np.interp(t, np.linspace(0, seconds, len(knots)), knots)
            inst = f * (1 + rng.uniform(-0.03, 0.01) * np.exp(-t / 0.03) + wander)
            ph = 2 * np.pi * np.cumsum(inst) / fs + rng.uniform(0, 2 * np.pi)
            y += level * np.tanh(drive * (np.sin(ph) + even * np.sin(2 * ph)))
        y = signal.sosfilt(sos_hp, y)
        y = signal.sosfilt(sos_lp, y + bell_gain * signal.sosfilt(sos_bell, y))
        y = signal.resample_poly(y, 1, os)
        return y * _ramp_envelope(len(y), sr, rng.uniform(0.004, 0.015), rng.uniform(0.02, 0.06))

    def honks() -> np.ndarray:
        k = int(rng.integers(1, 4))
        if k == 1:
            return honk(rng.uniform(0.3, 1.2))
        parts = []
        for i in range(k):
            parts.append(honk(rng.uniform(0.12, 0.5)))
            if i < k - 1:
                parts.append(np.zeros(round(rng.uniform(0.06, 0.25) * sr)))
        return np.concatenate(parts)

    if n is None:
        return honks()
    return _fill(lambda: honk(rng.uniform(1.5, 4.0)) if rng.random() < 0.3 else honks(),
                 n, rng, sr, (0.3, 1.5))


def _reverse_alarm(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    f = rng.uniform(1000, 1300)
    period, duty = rng.uniform(0.8, 1.1), rng.uniform(0.42, 0.58)
    # A piezo disc rounds off its square drive: odd harmonics far below a square's 1/n.
    h3 = rng.uniform(0.08, 0.3)
    harmonics = {1: 1.0, 2: rng.uniform(0, 0.06), 3: h3, 5: h3 * rng.uniform(0.2, 0.6)}
    ramp = rng.uniform(0.002, 0.008)
    on = duty * period
    if n is None:
        n = round(((int(rng.integers(3, 7)) - 1) * period + on + 0.05) * sr)
    t = np.arange(n) / sr
    ph = 2 * np.pi * f * t
    tone = sum(a * np.sin(h * ph + rng.uniform(0, 2 * np.pi) * (h > 1))
               for h, a in harmonics.items() if h * f < 0.45 * sr)
    pos = np.mod(t, period)
    gate = np.where(pos < on, np.clip(np.minimum(pos, on - pos) / ramp, 0, 1), 0.0)
    return tone * np.sin(0.5 * np.pi * gate) ** 2


def _ratchet(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    k_modes = int(rng.integers(3, 6))
    modes = np.sort(rng.uniform(2000, 8000, k_modes))
    decays = rng.uniform(0.002, 0.012, k_modes)
    amps = rng.uniform(0.3, 1.0, k_modes)
    body_hz = rng.uniform(500, 1500)  # lever and housing: a weak, lower ring
    base = rng.uniform(0.04, 0.12)
    m = round(0.08 * sr)

    def click() -> np.ndarray:
        j = rng.uniform(0.97, 1.03, k_modes)
        x = _modes(m, sr, modes * j, decays * rng.uniform(0.8, 1.2, k_modes),
                   amps * rng.uniform(0.6, 1.4, k_modes), rng.uniform(0, 2 * np.pi, k_modes))
        x += rng.uniform(0.5, 1.5) * _burst(m, sr, rng, 0.0003, 1500, 12000)
        x += rng.uniform(0.05, 0.25) * _modes(m, sr, body_hz * j[0], 0.01, 1.0, 0.0)
        return x

    def pull() -> np.ndarray:
        k = int(rng.integers(5, 15))
        slow = rng.uniform(-0.3, 0.8)  # the lever slows as the cable tightens (or is yanked)
        gaps = base * (1 + slow * np.linspace(0, 1, k - 1) ** 2) * rng.uniform(0.9, 1.1, k - 1)
        onsets = np.concatenate([[0.0], np.cumsum(np.clip(gaps, 0.035, 0.13))])
        gains = rng.lognormal(0, 0.25, k) * np.linspace(1, rng.uniform(0.7, 1.4), k)
        out = np.zeros(round(onsets[-1] * sr) + m)
        for t0, g in zip(onsets, gains):
            _add(out, g * click(), round(t0 * sr))
            if rng.random() < 0.5:  # the pawl bounces once off the tooth
                _add(out, g * rng.uniform(0.15, 0.4) * click(),
                     round((t0 + rng.uniform(0.002, 0.006)) * sr))
        return out

    return pull() if n is None else _fill(pull, n, rng, sr, (0.3, 1.2))


def _gearshift(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    f_body, d_body = rng.uniform(100, 400), rng.uniform(0.03, 0.09)
    f_upper = (f_body * rng.uniform(2.2, 3.6), rng.uniform(700, 2000))
    slide_lo, slide_hi = rng.uniform(300, 800), rng.uniform(1500, 3500)
    m = round(0.35 * sr)

    def slide() -> np.ndarray:
        k = round(rng.uniform(0.08, 0.3) * sr)
        # Friction is rough: the level flickers as the lever's bushing sticks and slips.
        grain = np.interp(np.arange(k), np.linspace(0, k, 40), rng.uniform(0.2, 1.0, 40))
        env = np.sin(np.pi * np.arange(k) / k) ** 1.5 * grain
        return rng.uniform(0.04, 0.15) * env * signal.sosfilt(
            _band(slide_lo, slide_hi, sr), rng.standard_normal(k))

    def clunk() -> np.ndarray:
        j = rng.uniform(0.97, 1.03)
        x = _modes(m, sr, [f_body * j, f_upper[0] * j, f_upper[1] * j],
                   [d_body, rng.uniform(0.015, 0.04), rng.uniform(0.004, 0.012)],
                   [1.0, rng.uniform(0.3, 0.6), rng.uniform(0.15, 0.4)],
                   [0.0, rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi)])
        x += rng.uniform(0.3, 0.8) * _burst(m, sr, rng, rng.uniform(0.001, 0.002), 60, 3000)
        for _ in range(int(rng.integers(1, 5))):  # loose parts rattle after the hit
            r = _modes(round(0.03 * sr), sr, rng.uniform(1200, 4000, 2), [0.003, 0.005],
                       rng.uniform(0.05, 0.2, 2), rng.uniform(0, 2 * np.pi, 2))
            _add(x, r, round(rng.uniform(0.008, 0.06) * sr))
        return x

    def operation() -> np.ndarray:
        parts = []
        for i in range(int(rng.integers(1, 4))):
            if i:  # e.g. out of gear, through neutral, into reverse
                parts.append(np.zeros(round(rng.uniform(0.1, 0.5) * sr)))
            s, c = slide(), clunk()
            throw = np.zeros(len(s) + len(c))
            throw[:len(s)] += s
            _add(throw, c, len(s) - round(0.005 * sr))  # the stop hits before the slide dies
            parts.append(throw)
        return np.concatenate(parts)

    return operation() if n is None else _fill(operation, n, rng, sr, (0.4, 1.5))


def _key_turning(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    n_keys = int(rng.integers(2, 6))
    key_modes = rng.uniform(3000, 10000, (n_keys, 3))
    key_decays = rng.uniform(0.008, 0.05, (n_keys, 3))
    lock_modes = rng.uniform(1500, 4500, 3)
    m = round(0.25 * sr)

    def strike() -> np.ndarray:
        pair = rng.choice(n_keys, size=min(2, n_keys), replace=False)  # two keys hit each other
        f = key_modes[pair].ravel() * rng.uniform(0.98, 1.02, 3 * len(pair))
        x = _modes(m, sr, f, key_decays[pair].ravel(), rng.uniform(0.2, 1.0, f.size),
                   rng.uniform(0, 2 * np.pi, f.size))
        return x + 0.5 * _burst(m, sr, rng, 0.0002, 3000, 15000)

    def lock_click(gain: float) -> np.ndarray:
        x = _modes(m, sr, lock_modes * rng.uniform(0.97, 1.03, 3), rng.uniform(0.003, 0.008, 3),
                   rng.uniform(0.4, 1.0, 3), rng.uniform(0, 2 * np.pi, 3))
        return gain * (x + _burst(m, sr, rng, 0.0004, 800, 12000))

    def turn() -> np.ndarray:
        jingle = rng.uniform(0.15, 0.5)
        scrape = rng.uniform(0.08, 0.2) if rng.random() < 0.6 else 0.0
        t_click = scrape + jingle * rng.uniform(0.3, 1.0)
        out = np.zeros(round((scrape + jingle + 0.25) * sr) + 2 * m)
        if scrape:  # the key sliding over the lock's pins
            k = round(scrape * sr)
            _add(out, rng.uniform(0.03, 0.1) * np.hanning(k)
                 * signal.sosfilt(_band(2000, 9000, sr), rng.standard_normal(k)), 0)
        # Keys swing and strike in clusters, not at uniformly random times.
        t = scrape + np.sort(jingle * rng.beta(0.7, 1.2, int(rng.integers(4, 13))))
        for t0 in t:
            _add(out, rng.uniform(0.2, 1.0) * strike(), round(t0 * sr))
        _add(out, lock_click(rng.uniform(1.0, 1.5)), round(t_click * sr))
        if rng.random() < 0.7:  # the cylinder drops into the next detent
            _add(out, lock_click(rng.uniform(0.4, 0.8)),
                 round((t_click + rng.uniform(0.04, 0.12)) * sr))
        return _trim_silence(out, sr)

    return turn() if n is None else _fill(turn, n, rng, sr, (0.4, 1.5))


def _human_voice(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    speaker = _draw_speaker(rng, "auto")

    def call() -> np.ndarray:
        text = VOICE_TEXTS[int(rng.integers(len(VOICE_TEXTS)))]
        return _speak(text, speaker, rng, sr, strict=False)

    return call() if n is None else _fill(call, n, rng, sr, (0.3, 1.2))


_CLASS_MODELS: dict[str, Callable[[np.random.Generator, int, int | None], np.ndarray]] = {
    "car_horn": _car_horn, "reverse_alarm": _reverse_alarm, "ratchet": _ratchet,
    "gearshift": _gearshift, "key_turning": _key_turning, "human_voice": _human_voice,
}


def _trim_silence(x: np.ndarray, sr: int, floor: float = 1e-3,
                  pad_s: float = 0.01) -> np.ndarray:
    """Cut leading/trailing samples below ``floor`` of the peak, keeping ``pad_s`` margins."""
    loud = np.flatnonzero(np.abs(x) > floor * np.max(np.abs(x), initial=0.0))
    if loud.size == 0:
        return x
    pad = round(pad_s * sr)
    return x[max(loud[0] - pad, 0):loud[-1] + pad + 1]


# --------------------------------------------------------------------------- voice synthesis
# A speaker is drawn once and then says several phrases (generate(..., seconds=...)).
# The formant voice is drawn first in every engine mode, so that "auto" without espeak-ng
# consumes the rng exactly like "formant" and gives the same samples.

_ESPEAK_VOICES = ("m1", "m2", "m3", "m4", "m5", "m6", "m7", "f1", "f2", "f3", "f4", "f5",
                  "klatt", "klatt2", "klatt3", "adam", "Andy", "david", "edward", "john",
                  "linda", "steph", "Annie", "belinda", "benjamin", "max", "paul", "robert")


def _find_espeak() -> bool:
    return espeak.available()


def voice_engine() -> str:
    """The engine that ``engine="auto"`` speaks with on this machine: the bundled espeak-ng
    (:data:`espeak.VERSION`) when its package is installed, else ``"formant"``. Models trained
    on generated speech record it (the voices, and so the trained weights, differ)."""
    return espeak.VERSION if _find_espeak() else "formant"


@dataclass(frozen=True)
class _FormantVoice:
    f0: float             # Hz, mean pitch
    tract: float          # formant scale: short vocal tracts (children, women) > 1
    breath: float         # aspiration noise relative to the glottal pulses
    rate: float           # duration multiplier (> 1 speaks slower)
    open_quotient: float  # fraction of the period the glottis opens; lower = brighter


@dataclass(frozen=True)
class _Speaker:
    formant: _FormantVoice
    espeak: tuple[str, int, int] | None  # (voice, pitch 0-99, words per minute)


def _draw_speaker(rng: np.random.Generator, engine: str) -> _Speaker:
    f0 = rng.uniform(110, 260)
    formant = _FormantVoice(f0=f0, tract=0.92 + 0.2 * (f0 - 110) / 150 + rng.normal(0, 0.03),
                            breath=rng.uniform(0.02, 0.12), rate=rng.uniform(0.8, 1.25),
                            open_quotient=rng.uniform(0.35, 0.5))
    espeak = None
    if engine == "espeak" or (engine == "auto" and _find_espeak()):
        lang = ("en", "en-us")[int(rng.integers(2))]
        voice = f"{lang}+{_ESPEAK_VOICES[int(rng.integers(len(_ESPEAK_VOICES)))]}"
        espeak = (voice, int(rng.integers(20, 81)), int(rng.integers(130, 191)))
    return _Speaker(formant, espeak)


def _speak(text: str, speaker: _Speaker, rng: np.random.Generator, sr: int,
           strict: bool) -> np.ndarray:
    if speaker.espeak is not None:
        voice, pitch, speed = speaker.espeak
        # A person never says a phrase the same way twice.
        pitch = int(np.clip(pitch + rng.integers(-6, 7), 0, 99))
        speed = int(speed * rng.uniform(0.9, 1.1))
        try:
            return _trim_silence(_espeak(text, voice, pitch, speed, sr), sr)
        except SoundError as exc:
            if strict:
                raise
            warnings.warn(f"{exc}; using the formant synthesizer instead", RuntimeWarning,
                          stacklevel=3)
    return _trim_silence(_formant_speech(text, speaker.formant, rng, sr), sr)


def _espeak(text: str, voice: str, pitch: int, speed: int, sr: int) -> np.ndarray:
    if not _find_espeak():
        raise SoundError("espeak-ng is not installed (the espeakng-loader package is missing)")
    x, file_sr = espeak.synthesize(text, voice, pitch, speed)
    if x.size == 0 or not np.any(x):
        raise SoundError(f"espeak-ng produced silence for {text!r}")
    ratio = Fraction(sr, int(file_sr))
    return signal.resample_poly(x, ratio.numerator, ratio.denominator)


# Peterson & Barney (1952) adult male formants F1-F3 in Hz; sonorants are weaker, voiced.
_VOWELS = {"a": (730, 1090, 2440), "e": (530, 1840, 2480), "i": (300, 2250, 3000),
           "o": (570, 840, 2410), "u": (300, 870, 2240), "y": (300, 2250, 3000)}
_SONORANTS = {"m": ((250, 1100, 2300), 0.3), "n": ((250, 1400, 2500), 0.3),
              "l": ((360, 1300, 2700), 0.5), "r": ((420, 1300, 1600), 0.5),
              "w": ((300, 700, 2200), 0.5), "j": ((280, 2200, 3000), 0.5)}
# Noise band (Hz) and level of fricatives and stop bursts.
_FRICATIVES = {"s": ((4000, 8000), 0.25), "z": ((4000, 8000), 0.2), "c": ((4000, 8000), 0.25),
               "x": ((3500, 8000), 0.25), "sh": ((2200, 5000), 0.3), "f": ((1500, 7000), 0.1),
               "v": ((1500, 7000), 0.08), "th": ((1500, 7000), 0.08), "h": ((500, 3000), 0.12)}
_STOPS = {"p": (500, 2500), "b": (500, 2500), "t": (3000, 7000), "d": (3000, 7000),
          "k": (1500, 3500), "g": (1500, 3500), "q": (1500, 3500), "ch": (2200, 5000)}
_BANDWIDTHS = (70.0, 100.0, 160.0, 220.0)


def _phones(text: str) -> list[tuple[str, str]]:
    """Spell ``text`` into (kind, symbol) pairs; no dictionary, so a rough English guess."""
    s, out, i = text.lower(), [], 0
    while i < len(s):
        two, c = s[i:i + 2], s[i]
        end_of_word = i + 1 >= len(s) or not s[i + 1].isalpha()
        if two in ("sh", "ch", "th"):
            out.append(("fric" if two != "ch" else "stop", two))
            i += 2
            continue
        if c in _VOWELS:
            word_has_vowel = any(k == "vowel" for k, _ in out[_word_start(out):])
            if not (c == "e" and end_of_word and word_has_vowel):  # silent final e
                out.append(("vowel", c))
        elif c in _SONORANTS:
            out.append(("sonorant", c))
        elif c in _FRICATIVES:
            out.append(("fric", c))
        elif c in _STOPS:
            out.append(("stop", c))
        elif c in ",;:":
            out.append(("pause", c))
        elif c.isspace() or c in "-.!?":
            out.append(("gap", c))
        i += 1
    return out


def _word_start(phones: list[tuple[str, str]]) -> int:
    for k in range(len(phones) - 1, -1, -1):
        if phones[k][0] in ("gap", "pause"):
            return k + 1
    return 0


def _formant_speech(text: str, v: _FormantVoice, rng: np.random.Generator,
                    sr: int) -> np.ndarray:
    phones = _phones(text)
    if not any(k in ("vowel", "sonorant") for k, _ in phones):
        raise SoundError(f"the formant synthesizer cannot speak {text!r} (no Latin vowels)")
    last_vowel = max(i for i, (k, _) in enumerate(phones) if k == "vowel" or k == "sonorant")
    # Segment table: start sample, length, formants (for voiced), voicing level.
    segs, noise, t = [], [], round(0.03 * sr)
    for i, (kind, sym) in enumerate(phones):
        if kind == "vowel":
            dur = rng.uniform(0.09, 0.16) * (rng.uniform(1.6, 2.6) if i == last_vowel else 1.0)
            segs.append((t, round(dur * v.rate * sr), _VOWELS[sym], 1.0))
        elif kind == "sonorant":
            formants, level = _SONORANTS[sym]
            segs.append((t, round(rng.uniform(0.05, 0.09) * v.rate * sr), formants, level))
        elif kind == "fric":
            (lo, hi), level = _FRICATIVES[sym]
            k = round(rng.uniform(0.06, 0.11) * v.rate * sr)
            noise.append((t, k, lo, hi, level))
            segs.append((t, k, None, 0.0))
        elif kind == "stop":  # closure silence, then the release burst
            closure = round(rng.uniform(0.03, 0.06) * v.rate * sr)
            burst = round(rng.uniform(0.01, 0.025) * sr)
            noise.append((t + closure, burst, *_STOPS[sym], 0.35))
            segs.append((t, closure + burst, None, 0.0))
        else:
            k = rng.uniform(0.12, 0.25) if kind == "pause" else rng.uniform(0.0, 0.04)
            segs.append((t, round(k * sr), None, 0.0))
        t += segs[-1][1]
    n = t + round(0.05 * sr)

    # Per-sample voicing level and formant targets; unvoiced spans borrow the next voiced
    # formants (coarticulation), and smoothing turns the steps into transitions.
    level = np.zeros(n)
    tracks = np.zeros((3, n))
    nxt = next(f for _, _, f, _ in reversed(segs) if f is not None)
    for start, k, formants, lv in reversed(segs):
        nxt = formants if formants is not None else nxt
        level[start:start + k] = lv
        tracks[:, start:start + k] = np.asarray(nxt, float)[:, None]
    tracks[:, t:] = tracks[:, t - 1:t]
    tracks[:, :segs[0][0]] = tracks[:, segs[0][0]:segs[0][0] + 1]
    level = _smooth(level, round(0.015 * sr))
    tracks = np.stack([_smooth(tr, round(0.03 * sr)) for tr in tracks]) * v.tract

    # Call intonation: rise to a peak on the stressed syllable, then fall; plus jitter.
    u = np.linspace(0, 1, n)
    contour = np.interp(u, [0, rng.uniform(0.15, 0.45), 1],
                        [1.0, rng.uniform(1.15, 1.5), rng.uniform(0.7, 0.9)])
    drift = np.interp(u, np.linspace(0, 1, 12), rng.normal(0, 0.02, 12))
    jitter = _smooth(rng.normal(0, 0.01, n), round(0.005 * sr))
    f0 = v.f0 * contour * (1 + drift + jitter)
    frac = np.mod(np.cumsum(f0) / sr, 1.0)
    # Rosenberg glottal flow pulse; its derivative (lip radiation) carries the harmonics.
    tp, tn = v.open_quotient, 0.16
    flow = np.where(frac < tp, 0.5 * (1 - np.cos(np.pi * frac / tp)),
                    np.where(frac < tp + tn, np.cos(0.5 * np.pi * (frac - tp) / tn), 0.0))
    source = np.diff(flow, prepend=0.0) * (sr / v.f0 / 10)
    source = (source + v.breath * rng.standard_normal(n)) * level
    voiced = _formant_filter(source, tracks, sr)
    voiced /= max(float(np.sqrt(np.mean(voiced[level > 0.5] ** 2))) if np.any(level > 0.5)
                  else 1.0, 1e-12)

    for start, k, lo, hi, lv in noise:
        burst = signal.sosfilt(_band(lo, hi, sr), rng.standard_normal(k))
        _add(voiced, lv * burst * _ramp_envelope(k, sr, 0.01, 0.015), start)
    return voiced


def _smooth(x: np.ndarray, width: int) -> np.ndarray:
    w = np.hanning(max(width, 3))
    return np.convolve(np.pad(x, (len(w) // 2, len(w) - 1 - len(w) // 2), mode="edge"),
                       w / w.sum(), mode="valid")


def _formant_filter(x: np.ndarray, tracks: np.ndarray, sr: int, block: int = 128) -> np.ndarray:
    """Cascade of Klatt resonators (F1-F3 tracked, fixed F4) updated every ``block`` samples.

    The filter states carry over from block to block, which keeps the output continuous
    while the coefficients glide; unit gain at DC keeps the vowels' relative levels natural.
    """
    f4 = np.full(tracks.shape[1], 3500.0 * tracks[2].mean() / 2500.0)
    freqs = np.vstack([tracks, f4])
    y = x.copy()
    for j, bw in enumerate(_BANDWIDTHS):
        zi = np.zeros(2)
        r = np.exp(-np.pi * bw / sr)
        for s in range(0, len(y), block):
            f = min(freqs[j, min(s + block // 2, len(y) - 1)], 0.45 * sr)
            b1, b2 = 2 * r * np.cos(2 * np.pi * f / sr), -r * r
            y[s:s + block], zi = signal.lfilter([1 - b1 - b2], [1, -b1, -b2], y[s:s + block], zi=zi)
    return y
