"""Checks shared by the sound bank's generators: sample rate, rng, lengths, text, and the
unit-RMS normalization every generated signal ends with."""

from __future__ import annotations

import math
import numbers

import numpy as np

from acoustic_sim.errors import SoundError

MAX_SECONDS = 600.0
"""Longest signal any generator makes, in s (guards against multi-gigabyte requests)."""

_MIN_RATE, _MAX_RATE = 8000, 384000


def check_rate(sample_rate) -> int:
    if (isinstance(sample_rate, bool) or not isinstance(sample_rate, (int, np.integer))
            or not _MIN_RATE <= sample_rate <= _MAX_RATE):
        raise SoundError(f"sample_rate must be an integer in [{_MIN_RATE}, {_MAX_RATE}] Hz, "
                         f"got {sample_rate!r}")
    return int(sample_rate)


def check_rng(rng) -> None:
    if not isinstance(rng, np.random.Generator):
        raise SoundError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")


def finite_number(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise SoundError(f"{what} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise SoundError(f"{what} must be finite, got {value!r}")
    return v


def num_samples(seconds, sr: int) -> int:
    s = finite_number(seconds, "seconds")
    if not 0.0 < s <= MAX_SECONDS:
        raise SoundError(f"seconds must be in (0, {MAX_SECONDS:g}] s, got {seconds!r}")
    n = round(s * sr)
    if n < 1:
        raise SoundError(f"seconds={seconds!r} is shorter than one sample at {sr} Hz")
    return n


def check_text(text) -> None:
    if not isinstance(text, str) or not text.strip() or len(text) > 500:
        raise SoundError(f"text must be a non-blank str of at most 500 characters, got {text!r}")


def normalized(x: np.ndarray, what: str) -> np.ndarray:
    rms = float(np.sqrt(np.mean(np.square(x))))
    if not math.isfinite(rms) or rms == 0.0:
        raise SoundError(f"{what} is silent (too short to hold any sound?)")
    return x / rms

