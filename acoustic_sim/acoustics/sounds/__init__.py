"""Sound bank: the six environmental sound classes, the paper's test signals, WAV loading.

Every signal is a float64 mono 1-D array at ``sample_rate`` (Hz), scaled to an RMS of
exactly 1.0 over the whole returned signal, so that the renderer's level in dB SPL at 1 m is
the signal's equivalent continuous level. Loaded WAV files are the exception: they keep
their recorded scale. Randomness comes only from the ``numpy.random.Generator`` passed in:
the same seed gives the same samples, bit for bit (``human_voice`` speaks with the espeak-ng
library that the project's ``espeakng-loader`` dependency bundles, the same on every machine
that installs it; see :mod:`~acoustic_sim.acoustics.sounds.espeak`).

The classes are the ones the paper's MelCNN is trained on (car horn, alarm, ratchet,
gearshift, key turning, human voice). They are synthesized from small physical models, and
every instance draws its own pitch, rhythm, timbre and duration, so that a classifier has to
learn the class and not one waveform. Where each lives:

- :mod:`.horn_alarm`: ``car_horn``, ``reverse_alarm`` (tonal warning sounds);
- :mod:`.mechanisms`: ``ratchet``, ``gearshift``, ``key_turning`` (struck metal parts);
- :mod:`.voice`, :mod:`.formant`, :mod:`.espeak`: ``human_voice``, a short call ("Musashi,
  over here!") through :func:`speech`;
- :mod:`.waves`: :func:`test_signal`, :func:`white_noise`, :func:`load_wav`;
- :mod:`.synth_blocks`, :mod:`.sound_checks`: what the models are built from and checked with.
- :mod:`.cutting`: the mechanisms' signals cut into what the world plays (the alarm's loop,
  one ratchet click per tooth, the gearshift's throws; used by :mod:`acoustic_sim.world.events`).

This module is the bank's front door: it names the classes, dispatches :func:`generate`,
and decides once per request which speech engine this machine has (:func:`voice_engine`).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from acoustic_sim.acoustics.sounds import espeak
from acoustic_sim.acoustics.sounds.horn_alarm import car_horn, reverse_alarm
from acoustic_sim.acoustics.sounds.mechanisms import gearshift, key_turning, ratchet
from acoustic_sim.acoustics.sounds.sound_checks import MAX_SECONDS, check_rate, check_rng, check_text, normalized, num_samples
from acoustic_sim.acoustics.sounds.synth_blocks import repeat_to_length
from acoustic_sim.acoustics.sounds.voice import VOICE_TEXTS, draw_speaker, speak
from acoustic_sim.acoustics.sounds.waves import TEST_WAVEFORMS, load_wav, test_signal, white_noise
from acoustic_sim.errors import SoundError
from acoustic_sim.frames import SAMPLE_RATE

__all__ = [
    "MAX_SECONDS", "SOUND_CLASSES", "TEST_WAVEFORMS", "VOICE_TEXTS", "available_sounds", "generate",
    "load_wav", "speech", "test_signal", "voice_engine", "white_noise",
]

SOUND_CLASSES: tuple[str, ...] = (
    "car_horn", "reverse_alarm", "ratchet", "gearshift", "key_turning", "human_voice",
)
"""The environmental sound classes, in the order of the classifier's outputs."""


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
    sr = check_rate(sample_rate)
    check_rng(rng)
    if not isinstance(name, str) or name not in available_sounds():
        raise SoundError(f"unknown sound {name!r}; valid names: {', '.join(available_sounds())}")
    n = None if seconds is None else num_samples(seconds, sr)
    if name == "white_noise":
        return white_noise(1.0 if seconds is None else seconds, rng, sample_rate=sr)
    x = _CLASS_MODELS[name](rng, sr, n)
    return normalized(x, f"{name} ({len(x)} samples)")



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
    sr = check_rate(sample_rate)
    check_rng(rng)
    check_text(text)
    if engine not in ("auto", "espeak", "formant"):
        raise SoundError(f"engine must be 'auto', 'espeak' or 'formant', got {engine!r}")
    installed = engine != "formant" and _find_espeak()
    speaker = draw_speaker(rng, engine == "espeak" or installed)
    x = speak(text, speaker, rng, sr, strict=engine == "espeak", espeak_installed=installed)
    return normalized(x, f"speech {text!r}")


def _find_espeak() -> bool:
    return espeak.available()


def voice_engine() -> str:
    """The engine that ``engine="auto"`` speaks with on this machine: the bundled espeak-ng
    (:data:`espeak.VERSION`) when its package is installed, else ``"formant"``. Models trained
    on generated speech record it (the voices, and so the trained weights, differ)."""
    return espeak.VERSION if _find_espeak() else "formant"


def _human_voice(rng: np.random.Generator, sr: int, n: int | None) -> np.ndarray:
    installed = _find_espeak()
    speaker = draw_speaker(rng, installed)

    def call() -> np.ndarray:
        text = VOICE_TEXTS[int(rng.integers(len(VOICE_TEXTS)))]
        return speak(text, speaker, rng, sr, strict=False, espeak_installed=installed)

    return call() if n is None else repeat_to_length(call, n, rng, sr, (0.3, 1.2))


_CLASS_MODELS: dict[str, Callable[[np.random.Generator, int, int | None], np.ndarray]] = {
    "car_horn": car_horn, "reverse_alarm": reverse_alarm, "ratchet": ratchet,
    "gearshift": gearshift, "key_turning": key_turning, "human_voice": _human_voice,
}
