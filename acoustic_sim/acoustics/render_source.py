"""What the renderer streams: a :class:`Source` with its per-source bookkeeping, its
checked signal (:func:`checked_signal`), and the :class:`EgoNoise` protocol for the
robot's own noise at the ears."""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np

from acoustic_sim.acoustics.room import ImageSources
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import P_REF


class EgoNoise(Protocol):
    """The robot's own noise at the ears (motors, gears): the world drives it later.

    ``__call__(n, rng)`` returns the next ``n`` samples of pressure (Pa) at both ears,
    shape (2, n).
    """

    def __call__(self, n: int, rng: np.random.Generator) -> np.ndarray: ...


@dataclasses.dataclass(eq=False)
class Source:
    """A sound source in the room (positions in metres, room frame).

    Attributes
    ----------
    name : str
        Unique among the renderer's sources.
    signal : numpy.ndarray, shape (n,)
        Mono signal, scaled so that its RMS is the source's level (see ``level_db``).
    position : numpy.ndarray, shape (3,)
        Metres, room frame, inside the room.
    level_db : float
        dB SPL at 1 m of a unit-RMS ``signal`` (free field, on axis).
    start : int
        Sample (project clock) at which the signal starts; silence before.
    loop : bool
        Repeat the signal forever instead of falling silent at its end.
    """

    name: str
    signal: np.ndarray
    position: np.ndarray
    level_db: float
    start: int = 0
    loop: bool = False
    # renderer state
    images: ImageSources | None = None
    row: int = 0  # the source's row in the renderer's input and spectrum buffers
    direct_key: tuple | None = None  # (HRIR index, whole delay, phase, distance) of the direct path
    direct: np.ndarray | None = None  # its spectrum (2, F) at the renderer's FFT size
    reflections: tuple | None = None  # geometry (idx, whole, phase, weights, key) of the last reflection update
    reflection_pose: tuple | None = None  # (head position, head rotation, source position, block) of that update
    reflected: np.ndarray | None = None  # spectrum (2, F) of the reflections plus the tail head
    band_factors: tuple | None = None  # SVD of the reflections' band damping
    placement: tuple | None = None  # reflections' position-only geometry for (head, source) positions (a cache)
    tail_head: np.ndarray | None = None  # (2, T): own tail up to the bus, minus the bus there
    tail_spectrum: np.ndarray | None = None  # its rFFT at the renderer's FFT size (a cache)
    fresh: bool = True  # no block rendered yet: the first response applies without a cross-fade

    def emitted(self, start: int, n: int) -> np.ndarray:
        """Pressure at 1 m (Pa, before spreading) for samples ``start .. start+n`` of the clock.

        Parameters
        ----------
        start : int
            First sample, on the project clock (any integer; before ``self.start`` is silence).
        n : int
            Number of samples, >= 1.

        Returns
        -------
        numpy.ndarray, shape (n,), float64
        """
        gain = P_REF * 10.0 ** (self.level_db / 20.0)
        sig = self.signal
        i0 = start - self.start
        if self.loop and i0 >= 0:
            i0 %= sig.size
            if i0 + n <= sig.size:
                return sig[i0 : i0 + n] * gain
        elif not self.loop and 0 <= i0 and i0 + n <= sig.size:
            return sig[i0 : i0 + n] * gain
        idx = np.arange(start, start + n) - self.start
        if self.loop:
            valid = idx >= 0
            out = np.where(valid, sig[np.mod(idx, sig.size)], 0.0)
        else:
            valid = (idx >= 0) & (idx < sig.size)
            out = np.where(valid, sig[np.clip(idx, 0, sig.size - 1)], 0.0)
        return out * gain


def mono_signal(signal, what: str) -> np.ndarray:
    """``signal`` as a float64 array, checked to be mono, non-empty and finite; ``what`` names
    it in the :class:`ConfigError` otherwise. Every path by which a signal enters the world
    (a renderer source, a scheduled or an event sound) checks it here."""
    x = np.asarray(signal, dtype=float)
    if x.ndim != 1 or x.size == 0 or not np.all(np.isfinite(x)):
        raise ConfigError(f"{what}: signal must be a non-empty finite 1-D array, got shape {x.shape}")
    return x


def checked_signal(name: str, signal, level_db: float) -> np.ndarray:
    """A source's signal as float64, checked with its level.

    Parameters
    ----------
    name : str
        The source's name, for the messages.
    signal : array_like, shape (n,)
        Mono, n >= 1, finite.
    level_db : float
        dB SPL at 1 m of a unit-RMS signal, -20 to 160.

    Returns
    -------
    numpy.ndarray, shape (n,), float64

    Raises
    ------
    ConfigError
        A signal that is not a non-empty finite 1-D array, or a level out of range.
    """
    sig = mono_signal(signal, f"source {name!r}")
    if not np.isfinite(level_db) or not -20 <= level_db <= 160:
        raise ConfigError(f"source {name!r}: level_db must be -20..160 dB SPL at 1 m, got {level_db}")
    return sig
