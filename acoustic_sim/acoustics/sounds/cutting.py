"""Cutting the mechanisms' sounds out of drawn signals: loops, clicks and throws.

A mechanism keeps its voice by being drawn once and then cut: the reverse alarm is one
beeper, cut to whole beep periods so that it loops seamlessly; the ratchet is one pull, cut
into its clicks; the gearshift is one ``gearshift`` signal, cut into its single throws (the
slide into the detent and its clunk). Every signal is drawn with
:func:`acoustic_sim.acoustics.sounds.generate` from the generator passed in, so the same
generator gives the same cuts. The event source (:mod:`acoustic_sim.world.events`) plays
them, one click per ratchet tooth and one throw per gear change.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import maximum_filter1d

from acoustic_sim.acoustics import sounds
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE


def onsets(x: np.ndarray, sample_rate: int, *, threshold: float, min_gap_s: float, smooth_s: float = 0.002) -> np.ndarray:
    """Sample indices where the envelope of ``x`` rises through ``threshold`` times its peak.

    The envelope is the running maximum of ``|x|`` over ``smooth_s``; rises closer than
    ``min_gap_s`` to the previous onset are ignored.
    """
    env = maximum_filter1d(np.abs(x), size=max(1, round(smooth_s * sample_rate)))
    on = env > threshold * env.max(initial=0.0)
    rises = np.flatnonzero(on[1:] & ~on[:-1]) + 1
    if on.size and on[0]:
        rises = np.r_[0, rises]
    keep: list[int] = []
    for r in rises:
        if not keep or r - keep[-1] >= min_gap_s * sample_rate:
            keep.append(int(r))
    return np.asarray(keep, dtype=np.int64)


def alarm_loop(rng: np.random.Generator, *, seconds: float = 6.0, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """One beeper's sound cut to whole beep periods, so that it loops with its own rhythm.

    The loop starts at the first beep's onset; its length is the whole number of periods
    (estimated from all beep onsets to a fraction of a sample) that the drawn signal holds.
    The cut falls in the silence between beeps, so the wrap cannot click.
    """
    x = sounds.generate("reverse_alarm", rng, seconds=seconds, sample_rate=sample_rate)
    beeps = onsets(x, sample_rate, threshold=0.3, min_gap_s=0.2)
    if beeps.size < 2:
        raise ConfigError(f"reverse alarm: {seconds} s holds {beeps.size} beep(s); draw a longer signal to find its period")
    period = (beeps[-1] - beeps[0]) / (beeps.size - 1)
    start = int(beeps[0])
    length = round((beeps.size - 1) * period)
    loop = x[start : start + length]
    return loop / np.sqrt(np.mean(loop**2))


def ratchet_clicks(rng: np.random.Generator, *, click_s: float = 0.035, sample_rate: int = SAMPLE_RATE) -> list[np.ndarray]:
    """The clicks of one ratchet: one ``ratchet`` pull cut at its click onsets.

    Each click runs from 1 ms before its onset to the next onset or ``click_s``, whichever
    comes first, with a 3 ms fade-out; the clicks keep their relative levels, scaled
    together to a mean power of 1.
    """
    x = sounds.generate("ratchet", rng, sample_rate=sample_rate)
    starts = onsets(x, sample_rate, threshold=0.2, min_gap_s=0.025, smooth_s=0.001)
    pre = round(0.001 * sample_rate)
    fade = round(0.003 * sample_rate)
    clicks = []
    for i, s in enumerate(starts):
        end = min(s + round(click_s * sample_rate), int(starts[i + 1]) - pre if i + 1 < starts.size else x.size)
        c = x[max(s - pre, 0) : end].copy()
        m = min(fade, c.size)
        c[c.size - m :] *= np.cos(0.5 * np.pi * np.arange(1, m + 1) / (m + 1))
        clicks.append(c)
    if not clicks:
        raise ConfigError("ratchet: the drawn pull has no clicks")
    return _unit_mean_power(clicks)


def gearshift_throws(rng: np.random.Generator, *, seconds: float = 8.0, sample_rate: int = SAMPLE_RATE) -> list[np.ndarray]:
    """Single lever throws (slide into a detent and its clunk) of one gearshift.

    One ``gearshift`` signal of ``seconds`` (one lever: the sound bank draws the lever's
    modes once per instance and repeats its throws) is cut at its silent gaps, which the
    model fills with exact zeros; the last throw, which the signal's end may have cut, is
    dropped.
    """
    x = sounds.generate("gearshift", rng, seconds=seconds, sample_rate=sample_rate)
    silent = np.r_[False, x == 0.0, False]
    edges = np.flatnonzero(np.diff(silent.astype(np.int8)))
    gaps = edges.reshape(-1, 2)  # [start, end) of each run of zeros
    gaps = gaps[gaps[:, 1] - gaps[:, 0] >= round(0.05 * sample_rate)]
    throws, start = [], 0
    for g0, g1 in gaps:
        if g0 > start:
            throws.append(x[start:g0].copy())
        start = g1
    if not throws:
        raise ConfigError(f"gearshift: {seconds} s holds no complete lever throw; draw a longer signal")
    return _unit_mean_power(throws)


def _unit_mean_power(parts: list[np.ndarray]) -> list[np.ndarray]:
    """Scale a bank of sounds together so that their mean power (each over its own
    length) is 1: a level then applies to the average sound, and their differences stay."""
    g = 1.0 / np.sqrt(np.mean([np.mean(p**2) for p in parts]))
    return [p * g for p in parts]


__all__ = ["alarm_loop", "gearshift_throws", "onsets", "ratchet_clicks"]
