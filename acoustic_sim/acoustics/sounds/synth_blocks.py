"""Building blocks of the synthesized sound classes: struck modes, noise bursts, band-pass
filters, envelopes, and the repetition that fills a requested length with events."""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy import signal


def modal_ring(n: int, sr: int, freqs, decays, amps, phases) -> np.ndarray:
    """Sum of exponentially decaying sinusoids: the ring of a struck object's modes."""
    freqs, decays, amps, phases = (np.atleast_1d(np.asarray(v, float))
                                   for v in (freqs, decays, amps, phases))
    keep = freqs < 0.45 * sr
    t = np.arange(n) / sr
    ring = (amps[keep, None] * np.exp(-t / decays[keep, None])
            * np.sin(2 * np.pi * freqs[keep, None] * t + phases[keep, None]))
    return ring.sum(axis=0)


def bandpass_sos(lo: float, hi: float, sr: int) -> np.ndarray:
    """Second-order-section band-pass, its upper edge kept below Nyquist."""
    hi = min(hi, 0.45 * sr)
    return signal.butter(2, [min(lo, 0.5 * hi), hi], "bandpass", fs=sr, output="sos")


def impact_burst(n: int, sr: int, rng: np.random.Generator, decay_s: float, lo: float,
                 hi: float) -> np.ndarray:
    """Band-passed, exponentially decaying noise: the broadband crack of an impact."""
    noise = rng.standard_normal(n) * np.exp(-np.arange(n) / (decay_s * sr))
    return signal.sosfilt(bandpass_sos(lo, hi, sr), noise)


def mix_at(out: np.ndarray, x: np.ndarray, start: int) -> None:
    """Mix ``x`` into ``out`` from sample ``start`` on, dropping what falls off the end."""
    start = int(start)
    m = min(len(x), len(out) - start)
    if m > 0:
        out[start:start + m] += x[:m]


def fit_length(x: np.ndarray, n: int, sr: int) -> np.ndarray:
    """Exactly ``n`` samples: pad with silence, or cut with a short fade (no click)."""
    if len(x) < n:
        return np.concatenate([x, np.zeros(n - len(x))])
    x = x[:n].copy()
    f = min(n, round(0.005 * sr))
    x[n - f:] *= np.cos(0.5 * np.pi * np.arange(1, f + 1) / (f + 1))
    return x


def repeat_to_length(event: Callable[[], np.ndarray], n: int, rng: np.random.Generator, sr: int,
                     gap_s: tuple[float, float]) -> np.ndarray:
    """Repeat ``event()`` with random silent pauses until ``n`` samples are covered."""
    parts, total = [], 0
    while total < n:
        x = event()
        if not parts:  # start on the sound, so that even a short request is not silent
            x = trim_silence(x, sr, pad_s=0.0)
        gap = np.zeros(round(rng.uniform(*gap_s) * sr))
        parts += [x, gap]
        total += len(x) + len(gap)
    return fit_length(np.concatenate(parts), n, sr)


def ramp_envelope(n: int, sr: int, attack_s: float, release_s: float) -> np.ndarray:
    t = np.arange(n) / sr
    rise = np.clip(t / attack_s, 0, 1)
    fall = np.clip((n / sr - t) / release_s, 0, 1)
    return np.sin(0.5 * np.pi * np.minimum(rise, fall)) ** 2



def trim_silence(x: np.ndarray, sr: int, floor: float = 1e-3,
                 pad_s: float = 0.01) -> np.ndarray:
    """Cut leading/trailing samples below ``floor`` of the peak, keeping ``pad_s`` margins."""
    loud = np.flatnonzero(np.abs(x) > floor * np.max(np.abs(x), initial=0.0))
    if loud.size == 0:
        return x
    pad = round(pad_s * sr)
    return x[max(loud[0] - pad, 0):loud[-1] + pad + 1]

