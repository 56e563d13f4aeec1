"""What the sound-data generator draws (:class:`SoundDataConfig`) and what it returns
(:class:`SoundExamples`): the classes, the rooms, and the shapes of the labelled windows.

Windows end every ``window_hop_frames`` frames from frame ``first_window_frame`` on.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.auditory.features import MEL_FRAMES, N_MELS
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

CLASSES: tuple[str, ...] = sounds.SOUND_CLASSES
"""The six classes, in the order of every label array."""

ROOMS: tuple[str, ...] = ("anechoic", "car_cabin", "lab", "conference")
"""Rooms the examples are rendered in by default."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class SoundDataConfig:
    """How scenes are drawn (see :mod:`~acoustic_sim.auditory.sound_data.scene_mix`).

    Parameters
    ----------
    scene_seconds : float
        Length of one scene in s (0.5-30); each gives several windows.
    first_window_frame : int
        Frame number (1-based) at which the first window ends, >= 25; earlier frames
        include the silence before the scene.
    window_hop_frames : int
        Frames between the ends of consecutive windows of a scene (>= 1).
    class_count_probs : tuple of float
        Probability of 0, 1, 2, ... distinct classes in a scene (sums to 1; at most 6).
    sound_seconds : tuple of float
        Range (s) of the length of each class's instance.
    start_seconds : tuple of float
        Range (s, relative to the scene start) of each instance's start.
    snr_db : tuple of float
        Range (dB) of each class's power at the ears over the background's.
    background_db_spl : tuple of float
        Range (dB SPL at the ears) of the background noise.
    noise_slope_db_per_octave : tuple of float
        Range of the background's spectral slope (power, dB per octave; -3 pink, -6 brown).
    rooms : tuple of str
        Room presets drawn uniformly.
    audible_snr_db : float
        Local SNR (dB) a mel band needs for the class to count as audible in it.
    audible_min_bands : int
        Mel bands that must pass ``audible_snr_db`` for an audible frame (1-128).
    label_frames : tuple of int
        ``(a0, a1)``: the target ramps from 0 at ``a0`` audible frames to 1 at ``a1``.
    pool_size : int
        Sound instances kept per class by :func:`generate_examples` (:class:`SoundPool`).
    pool_reuse : int
        Mean number of scenes an instance serves (1: every sound is fresh).
    """

    scene_seconds: float = 3.0
    first_window_frame: int = 30
    window_hop_frames: int = 12
    class_count_probs: tuple[float, ...] = (0.05, 0.3, 0.4, 0.25)
    sound_seconds: tuple[float, float] = (1.5, 3.0)
    start_seconds: tuple[float, float] = (-1.0, 2.2)
    snr_db: tuple[float, float] = (0.0, 30.0)
    background_db_spl: tuple[float, float] = (30.0, 70.0)
    noise_slope_db_per_octave: tuple[float, float] = (-6.0, 0.0)
    rooms: tuple[str, ...] = ROOMS
    audible_snr_db: float = 6.0
    audible_min_bands: int = 5
    label_frames: tuple[int, int] = (2, 6)
    pool_size: int = 40
    pool_reuse: int = 4

    def __post_init__(self) -> None:
        def rng_pair(name, lo, hi):
            v = getattr(self, name)
            if len(v) != 2 or not all(math.isfinite(x) for x in v) or not lo <= v[0] <= v[1] <= hi:
                raise ConfigError(f"SoundDataConfig.{name} must be (low, high) with {lo} <= low <= high <= {hi}, got {v}")

        if not 0.5 <= self.scene_seconds <= 30:
            raise ConfigError(f"SoundDataConfig.scene_seconds must be 0.5-30 s, got {self.scene_seconds}")
        n_frames = int(self.scene_seconds * 62.5)
        if not MEL_FRAMES <= self.first_window_frame <= n_frames:
            raise ConfigError(f"SoundDataConfig.first_window_frame must be {MEL_FRAMES}..{n_frames} "
                              f"(frames in a scene), got {self.first_window_frame}")
        if self.window_hop_frames < 1:
            raise ConfigError(f"SoundDataConfig.window_hop_frames must be >= 1, got {self.window_hop_frames}")
        p = np.asarray(self.class_count_probs, float)
        if p.size < 1 or p.size > len(CLASSES) + 1 or np.any(p < 0) or not np.isclose(p.sum(), 1.0):
            raise ConfigError(f"SoundDataConfig.class_count_probs must be 1-{len(CLASSES) + 1} "
                              f"probabilities summing to 1, got {self.class_count_probs}")
        rng_pair("sound_seconds", 0.05, 60.0)
        rng_pair("start_seconds", -60.0, self.scene_seconds)
        rng_pair("snr_db", -40.0, 60.0)
        rng_pair("background_db_spl", 0.0, 100.0)
        rng_pair("noise_slope_db_per_octave", -12.0, 6.0)
        if not self.rooms or any(r not in ("anechoic", "car_cabin", "lab", "conference") for r in self.rooms):
            raise ConfigError(f"SoundDataConfig.rooms must be presets among {ROOMS}, got {self.rooms}")
        if not 1 <= self.audible_min_bands <= N_MELS:
            raise ConfigError(f"SoundDataConfig.audible_min_bands must be 1..{N_MELS}, got {self.audible_min_bands}")
        if self.pool_size < 1 or self.pool_reuse < 1:
            raise ConfigError(f"SoundDataConfig.pool_size and pool_reuse must be >= 1, got {self.pool_size}, {self.pool_reuse}")
        a0, a1 = self.label_frames
        if not 0 <= a0 < a1 <= MEL_FRAMES:
            raise ConfigError(f"SoundDataConfig.label_frames must be (a0, a1) with 0 <= a0 < a1 <= {MEL_FRAMES}, "
                              f"got {self.label_frames}")

    def windows_per_scene(self) -> int:
        """Number of windows one scene yields."""
        n_frames = _frames_in(self.scene_seconds)
        return (n_frames - self.first_window_frame) // self.window_hop_frames + 1


@dataclasses.dataclass(frozen=True)
class SoundExamples:
    """A set of labelled binaural windows.

    Attributes
    ----------
    patches : numpy.ndarray
        (N, 2, 25, 128): normalised log-mel patches (left, right), values in [-1, 0];
        float32 unless another dtype was asked for.
    targets : numpy.ndarray
        float32 (N, 2, 6): soft per-ear targets in [0, 1] (the ramp of
        :mod:`~acoustic_sim.auditory.sound_data.windows`).
    labels : numpy.ndarray
        bool (N, 6): binaural hard labels, ``max over ears of targets >= 0.5``.
    volumes : numpy.ndarray
        float64 (N, 2): ear volumes V_l, V_r (mean over the window's frames of
        :func:`~acoustic_sim.auditory.features.ear_volume`, full-scale units squared).
    room : numpy.ndarray
        int8 (N,): index into the config's ``rooms`` of each window's room.
    spectrum_sum : numpy.ndarray
        float64 (6, 1025): per class, the sum of its unit-sum power spectra over the frames
        (and ears) where it was audible.
    spectrum_frames : numpy.ndarray
        int64 (6,): number of those frames per class.
    """

    patches: np.ndarray
    targets: np.ndarray
    labels: np.ndarray
    volumes: np.ndarray
    room: np.ndarray
    spectrum_sum: np.ndarray
    spectrum_frames: np.ndarray

    def __len__(self) -> int:
        return int(self.labels.shape[0])


def _frames_in(seconds: float) -> int:
    n = round(seconds * SAMPLE_RATE)
    return int(np.floor(n * 62.5 / SAMPLE_RATE))


def _progress(total: int, desc: str, enabled: bool):
    from acoustic_sim.progress import progress_bar

    return progress_bar(total=total, desc=desc, disable=not enabled, unit="ex" if "example" in desc else "it",
                dynamic_ncols=True, leave=False)
