"""The mechanical sounds of the bank: clicks, clunks and jingles of struck metal parts.

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

Each model is ``model(rng, sample_rate, n)``: one natural instance when ``n`` is None,
else exactly ``n`` samples; not yet normalized (:func:`acoustic_sim.acoustics.sounds.generate`
does that).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from acoustic_sim.acoustics.sounds.synth_blocks import (
    bandpass_sos, impact_burst, mix_at, modal_ring, repeat_to_length, trim_silence,
)


def ratchet(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    k_modes = int(rng.integers(3, 6))
    modes = np.sort(rng.uniform(2000, 8000, k_modes))
    decays = rng.uniform(0.002, 0.012, k_modes)
    amps = rng.uniform(0.3, 1.0, k_modes)
    body_hz = rng.uniform(500, 1500)  # lever and housing: a weak, lower ring
    base = rng.uniform(0.04, 0.12)
    m = round(0.08 * sr)

    def click() -> np.ndarray:
        j = rng.uniform(0.97, 1.03, k_modes)
        x = modal_ring(m, sr, modes * j, decays * rng.uniform(0.8, 1.2, k_modes),
                       amps * rng.uniform(0.6, 1.4, k_modes), rng.uniform(0, 2 * np.pi, k_modes))
        x += rng.uniform(0.5, 1.5) * impact_burst(m, sr, rng, 0.0003, 1500, 12000)
        x += rng.uniform(0.05, 0.25) * modal_ring(m, sr, body_hz * j[0], 0.01, 1.0, 0.0)
        return x

    def pull() -> np.ndarray:
        k = int(rng.integers(5, 15))
        slow = rng.uniform(-0.3, 0.8)  # the lever slows as the cable tightens (or is yanked)
        gaps = base * (1 + slow * np.linspace(0, 1, k - 1) ** 2) * rng.uniform(0.9, 1.1, k - 1)
        onsets = np.concatenate([[0.0], np.cumsum(np.clip(gaps, 0.035, 0.13))])
        gains = rng.lognormal(0, 0.25, k) * np.linspace(1, rng.uniform(0.7, 1.4), k)
        out = np.zeros(round(onsets[-1] * sr) + m)
        for t0, g in zip(onsets, gains):
            mix_at(out, g * click(), round(t0 * sr))
            if rng.random() < 0.5:  # the pawl bounces once off the tooth
                mix_at(out, g * rng.uniform(0.15, 0.4) * click(),
                       round((t0 + rng.uniform(0.002, 0.006)) * sr))
        return out

    return pull() if n is None else repeat_to_length(pull, n, rng, sr, (0.3, 1.2))


def gearshift(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
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
            bandpass_sos(slide_lo, slide_hi, sr), rng.standard_normal(k))

    def clunk() -> np.ndarray:
        j = rng.uniform(0.97, 1.03)
        x = modal_ring(m, sr, [f_body * j, f_upper[0] * j, f_upper[1] * j],
                       [d_body, rng.uniform(0.015, 0.04), rng.uniform(0.004, 0.012)],
                   [1.0, rng.uniform(0.3, 0.6), rng.uniform(0.15, 0.4)],
                   [0.0, rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi)])
        x += rng.uniform(0.3, 0.8) * impact_burst(m, sr, rng, rng.uniform(0.001, 0.002), 60, 3000)
        for _ in range(int(rng.integers(1, 5))):  # loose parts rattle after the hit
            r = modal_ring(round(0.03 * sr), sr, rng.uniform(1200, 4000, 2), [0.003, 0.005],
                           rng.uniform(0.05, 0.2, 2), rng.uniform(0, 2 * np.pi, 2))
            mix_at(x, r, round(rng.uniform(0.008, 0.06) * sr))
        return x

    def operation() -> np.ndarray:
        parts = []
        for i in range(int(rng.integers(1, 4))):
            if i:  # e.g. out of gear, through neutral, into reverse
                parts.append(np.zeros(round(rng.uniform(0.1, 0.5) * sr)))
            s, c = slide(), clunk()
            throw = np.zeros(len(s) + len(c))
            throw[:len(s)] += s
            mix_at(throw, c, len(s) - round(0.005 * sr))  # the stop hits before the slide dies
            parts.append(throw)
        return np.concatenate(parts)

    return operation() if n is None else repeat_to_length(operation, n, rng, sr, (0.4, 1.5))


def key_turning(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    n_keys = int(rng.integers(2, 6))
    key_modes = rng.uniform(3000, 10000, (n_keys, 3))
    key_decays = rng.uniform(0.008, 0.05, (n_keys, 3))
    lock_modes = rng.uniform(1500, 4500, 3)
    m = round(0.25 * sr)

    def strike() -> np.ndarray:
        pair = rng.choice(n_keys, size=min(2, n_keys), replace=False)  # two keys hit each other
        f = key_modes[pair].ravel() * rng.uniform(0.98, 1.02, 3 * len(pair))
        x = modal_ring(m, sr, f, key_decays[pair].ravel(), rng.uniform(0.2, 1.0, f.size),
                       rng.uniform(0, 2 * np.pi, f.size))
        return x + 0.5 * impact_burst(m, sr, rng, 0.0002, 3000, 15000)

    def lock_click(gain: float) -> np.ndarray:
        x = modal_ring(m, sr, lock_modes * rng.uniform(0.97, 1.03, 3), rng.uniform(0.003, 0.008, 3),
                       rng.uniform(0.4, 1.0, 3), rng.uniform(0, 2 * np.pi, 3))
        return gain * (x + impact_burst(m, sr, rng, 0.0004, 800, 12000))

    def turn() -> np.ndarray:
        jingle = rng.uniform(0.15, 0.5)
        scrape = rng.uniform(0.08, 0.2) if rng.random() < 0.6 else 0.0
        t_click = scrape + jingle * rng.uniform(0.3, 1.0)
        out = np.zeros(round((scrape + jingle + 0.25) * sr) + 2 * m)
        if scrape:  # the key sliding over the lock's pins
            k = round(scrape * sr)
            mix_at(out, rng.uniform(0.03, 0.1) * np.hanning(k)
                   * signal.sosfilt(bandpass_sos(2000, 9000, sr), rng.standard_normal(k)), 0)
        # Keys swing and strike in clusters, not at uniformly random times.
        t = scrape + np.sort(jingle * rng.beta(0.7, 1.2, int(rng.integers(4, 13))))
        for t0 in t:
            mix_at(out, rng.uniform(0.2, 1.0) * strike(), round(t0 * sr))
        mix_at(out, lock_click(rng.uniform(1.0, 1.5)), round(t_click * sr))
        if rng.random() < 0.7:  # the cylinder drops into the next detent
            mix_at(out, lock_click(rng.uniform(0.4, 0.8)),
                   round((t_click + rng.uniform(0.04, 0.12)) * sr))
        return trim_silence(out, sr)

    return turn() if n is None else repeat_to_length(turn, n, rng, sr, (0.4, 1.5))

