"""The tonal warning sounds of the bank: the car horn and the reverse (backup) alarm.

``car_horn``
    Two electromagnetic disc horns a minor or major third apart (low one 370-500 Hz),
    slightly off just intonation. Each diaphragm slams into its stop, modelled by a driven
    ``tanh`` (rendered 4x oversampled so the harmonics do not alias), and the trumpet adds
    a high-pass and a 1.5-2.8 kHz resonance. Fast attack; one long honk or 2-3 short ones.
``reverse_alarm``
    A piezo backup beeper: a 1000-1300 Hz tone with weak odd harmonics (a square wave
    smoothed by the transducer), gated at a 0.8-1.1 s period with a ~50 % duty cycle.

Each model is ``model(rng, sample_rate, n)``: one natural instance when ``n`` is None,
else exactly ``n`` samples; not yet normalized (:func:`acoustic_sim.acoustics.sounds.generate`
does that).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from acoustic_sim.acoustics.sounds.synth_blocks import ramp_envelope, repeat_to_length


def car_horn(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
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
        return y * ramp_envelope(len(y), sr, rng.uniform(0.004, 0.015), rng.uniform(0.02, 0.06))

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
    return repeat_to_length(lambda: honk(rng.uniform(1.5, 4.0)) if rng.random() < 0.3 else honks(),
                            n, rng, sr, (0.3, 1.5))


def reverse_alarm(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
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

