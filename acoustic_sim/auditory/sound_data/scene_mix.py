"""One binaural scene of the sound data: sounds through BRIRs, background noise, the ears.

A scene (``scene_seconds`` long) is made like this:

1. **Room and positions.** A room is drawn from ``rooms`` (default ``anechoic``,
   ``car_cabin``, ``lab``, ``conference``). Sources go through binaural room impulse
   responses (BRIRs) from a :class:`BRIRBank`: per room, BRIRs precomputed with
   :meth:`BinauralRenderer.impulse_response` (KEMAR, image sources plus diffuse tail) for
   random source directions (azimuth uniform, elevation -30..60 deg) and distances
   (0.5-3 m, kept 0.1 m inside the walls). Convolving with a bank is exactly what the
   streaming renderer does for a static head and source, at a fraction of its cost.
2. **Sounds.** 0-3 distinct classes (``class_count_probs`` = 5/30/40/25 %) each play a
   1.5-3 s crop of an instance of :func:`acoustic_sim.acoustics.sounds.generate` (its
   own pitch, rhythm and pauses; a :class:`SoundPool` recycles each instance for about
   ``pool_reuse`` = 4 scenes with other crops: about 6 instead of 8.5 ms per window),
   starting anywhere from 1 s before the scene to 0.8 s before its end, so
   windows see onsets, steady parts, pauses, offsets and reverberant tails.
3. **Levels.** A diffuse background noise (:func:`diffuse_noise`: spectral slope
   -6..0 dB/octave, coherent between the ears below ~700 Hz) at ``background_db_spl``
   (30-70 dB SPL at the ears) and each class at an SNR of ``snr_db`` (0-30 dB): the
   instance's level (unit RMS over the whole instance) times the BRIR's energy gain, over
   the background power. The paper's room experiment (73-76 dB SPL at 1.5 m over a 58 dB
   background) sits in the middle of that range. Levels are set on the instance, not on
   the part that falls in the scene, so a crop that is mostly a pause stays quiet.
4. **Ears.** The sum goes through the ear unit's :class:`~acoustic_sim.acoustics.
   microphone.Microphone` (self-noise, high-pass, 24-bit ADC) and the front end
   (:func:`~acoustic_sim.auditory.frontend.analyze`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal as sp_signal

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.auditory.sound_data.brir_bank import BRIRBank
from acoustic_sim.auditory.sound_data.data_types import CLASSES, SoundDataConfig
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, db_spl_to_pa


def diffuse_noise(n: int, rng: np.random.Generator, *, slope_db_per_octave: float = -3.0,
                  crossover_hz: float = 700.0, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Two-ear diffuse background noise with a power-law spectrum, unit mean power.

    Parameters
    ----------
    n : int
        Samples per ear (>= 2).
    rng : numpy.random.Generator
        The only source of randomness.
    slope_db_per_octave : float
        Power spectral density slope in dB per octave (0 white, -3 pink, -6 brown),
        applied from 50 Hz up (flat below, nothing below 20 Hz).
    crossover_hz : float
        Interaural coherence is ``1 / (1 + (f / crossover_hz)**2)``: a diffuse field is
        coherent where the head is small against the wavelength, incoherent above.
    sample_rate : int
        Hz.

    Returns
    -------
    numpy.ndarray
        float64 (2, n), mean square over both ears exactly 1 (dimensionless; scale to Pa).
    """
    if n < 2:
        raise ConfigError(f"noise length must be >= 2 samples, got {n}")
    f = np.fft.rfftfreq(n, 1.0 / sample_rate)
    shape = (np.maximum(f, 50.0) / 1000.0) ** (slope_db_per_octave / (20.0 * np.log10(2.0)))
    shape[f < 20.0] = 0.0
    gamma = 1.0 / (1.0 + (f / crossover_hz) ** 2)
    z = rng.standard_normal((2, 2, f.size))
    z = z[:, 0] + 1j * z[:, 1]
    spec = np.stack([z[0], gamma * z[0] + np.sqrt(1.0 - gamma**2) * z[1]]) * shape
    x = np.fft.irfft(spec, n=n, axis=-1)
    return x / np.sqrt(np.mean(x**2))


class SoundPool:
    """Sound instances recycled across scenes, to spend less time synthesising.

    Per class, up to ``size`` instances of ``seconds`` s from
    :func:`acoustic_sim.acoustics.sounds.generate` (unit RMS over the instance). Each
    request returns a random crop of a random instance; a fresh instance is made (into a
    free slot, else replacing a random one) while the pool fills and then with probability
    ``1 / reuse``, so on average an instance serves ``reuse`` scenes, each time with another
    crop, room position, level and background.

    Parameters
    ----------
    seconds : float
        Length of each instance (s); crops are at most this long.
    size : int
        Instances kept per class (>= 1).
    reuse : int
        Mean number of requests an instance serves (>= 1; 1 makes every request fresh).
    """

    FADE_S = 0.005
    """Fade (s) at a crop's cut ends, so a cut never clicks."""

    def __init__(self, *, seconds: float, size: int, reuse: int) -> None:
        if size < 1 or reuse < 1 or not seconds > 0:
            raise ConfigError(f"SoundPool needs seconds > 0, size >= 1 and reuse >= 1, got {seconds}, {size}, {reuse}")
        self.seconds, self.size, self.reuse = float(seconds), int(size), int(reuse)
        self.instances: dict[int, list[np.ndarray]] = {c: [] for c in range(len(CLASSES))}

    def crop(self, c: int, seconds: float, rng: np.random.Generator) -> np.ndarray:
        """A ``seconds``-long (at most the instance length) crop of an instance of class index ``c``."""
        pool = self.instances[c]
        if len(pool) < self.size or rng.random() < 1.0 / self.reuse:
            x = sounds.generate(CLASSES[c], rng, seconds=self.seconds).astype(np.float32)
            if len(pool) < self.size:
                pool.append(x)
            else:
                pool[int(rng.integers(self.size))] = x
        else:
            x = pool[int(rng.integers(len(pool)))]
        n = min(round(seconds * SAMPLE_RATE), x.size)
        offset = int(rng.integers(0, x.size - n + 1))
        out = x[offset:offset + n].astype(np.float64)
        f = min(round(self.FADE_S * SAMPLE_RATE), n // 2)
        ramp = np.sin(0.5 * np.pi * (np.arange(f) + 0.5) / f) ** 2
        if offset > 0:
            out[:f] *= ramp
        if offset + n < x.size:
            out[n - f:] *= ramp[::-1]
        return out


@dataclasses.dataclass
class _Scene:
    digital: np.ndarray  # (2, n) float32 microphone output
    classes: list[int]  # classes present in the scene
    ears: list[np.ndarray]  # per present class: (2, n) eardrum pressure (Pa)
    noise: np.ndarray  # (2, n) background pressure (Pa)
    room: int


def _scene(cfg: SoundDataConfig, bank: BRIRBank, rng: np.random.Generator, pool: SoundPool) -> _Scene:
    sr = SAMPLE_RATE
    n = round(cfg.scene_seconds * sr)
    room_i = int(rng.integers(len(cfg.rooms)))
    brirs = bank.brirs[cfg.rooms[room_i]]
    k = int(rng.choice(len(cfg.class_count_probs), p=np.asarray(cfg.class_count_probs, float)))
    chosen = sorted(int(c) for c in rng.choice(len(CLASSES), size=k, replace=False))
    background_pa = db_spl_to_pa(rng.uniform(*cfg.background_db_spl))
    classes, ears = [], []
    for c in chosen:
        brir = brirs[int(rng.integers(len(brirs)))]
        start = round(rng.uniform(*cfg.start_seconds) * sr)
        snr = rng.uniform(*cfg.snr_db)
        x = pool.crop(c, rng.uniform(*cfg.sound_seconds), rng)
        lo, hi = max(start, 0), min(start + x.size, n)
        if hi <= lo or not np.any(x[lo - start:hi - start]):
            continue  # nothing of the instance plays within the scene
        dry = np.zeros(n)
        dry[lo:hi] = x[lo - start:hi - start]
        wet = sp_signal.oaconvolve(dry[None, :], brir, axes=1)[:, :n]
        # The level is set on the instance as a whole (unit RMS) through the BRIR's energy
        # gain, not on the part that falls in the scene: a crop that is mostly a pause must
        # stay quiet, not be blown up to the target level.
        gain = background_pa * 10.0 ** (snr / 20.0) / math.sqrt(float(np.mean(np.sum(brir**2, axis=1))))
        classes.append(c)
        ears.append(wet * gain)
    noise = diffuse_noise(n, rng, slope_db_per_octave=rng.uniform(*cfg.noise_slope_db_per_octave)) * background_pa
    pressure = noise + (np.sum(ears, axis=0) if ears else 0.0)
    digital = Microphone(rng=rng)(pressure)
    return _Scene(digital, classes, ears, noise, room_i)
