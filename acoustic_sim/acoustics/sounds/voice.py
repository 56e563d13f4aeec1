"""Speakers of the ``human_voice`` class: who says the phrase, and with which engine.

A speaker is drawn once and then says several phrases (``generate(..., seconds=...)``),
each a little differently. The engine is the bundled ``espeak-ng``
(:mod:`~acoustic_sim.acoustics.sounds.espeak`) with a random voice, pitch and speed, or
where its wheel does not exist the formant synthesizer
(:mod:`~acoustic_sim.acoustics.sounds.formant`). Whether espeak-ng is installed is the
caller's to say (:func:`acoustic_sim.acoustics.sounds.voice_engine` tells it), so that one
place decides it for every phrase.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from scipy import signal

from acoustic_sim.acoustics.sounds import espeak
from acoustic_sim.acoustics.sounds.formant import FormantVoice, formant_speech
from acoustic_sim.acoustics.sounds.synth_blocks import trim_silence
from acoustic_sim.errors import SoundError

VOICE_TEXTS: tuple[str, ...] = (
    "Musashi!", "Over here!", "Musashi, over here!", "Hey, Musashi!", "Hello!",
)
"""Phrases that ``human_voice`` instances call out."""

ESPEAK_VOICES = ("m1", "m2", "m3", "m4", "m5", "m6", "m7", "f1", "f2", "f3", "f4", "f5",
                 "klatt", "klatt2", "klatt3", "adam", "Andy", "david", "edward", "john",
                 "linda", "steph", "Annie", "belinda", "benjamin", "max", "paul", "robert")
"""espeak-ng voice variants a speaker draws from."""


@dataclass(frozen=True)
class Speaker:
    """A drawn speaker: its formant voice, and its espeak-ng voice if it speaks with that."""

    formant: FormantVoice
    espeak: tuple[str, int, int] | None  # (voice, pitch 0-99, words per minute)


def draw_speaker(rng: np.random.Generator, use_espeak: bool) -> Speaker:
    """Draw a speaker. The formant voice is drawn first in every engine mode, so that
    "auto" without espeak-ng consumes the rng exactly like "formant" and gives the same
    samples; ``use_espeak`` adds an espeak-ng voice, pitch and speed."""
    f0 = rng.uniform(110, 260)
    formant = FormantVoice(f0=f0, tract=0.92 + 0.2 * (f0 - 110) / 150 + rng.normal(0, 0.03),
                           breath=rng.uniform(0.02, 0.12), rate=rng.uniform(0.8, 1.25),
                           open_quotient=rng.uniform(0.35, 0.5))
    voice_params = None
    if use_espeak:
        lang = ("en", "en-us")[int(rng.integers(2))]
        voice = f"{lang}+{ESPEAK_VOICES[int(rng.integers(len(ESPEAK_VOICES)))]}"
        voice_params = (voice, int(rng.integers(20, 81)), int(rng.integers(130, 191)))
    return Speaker(formant, voice_params)


def speak(text: str, speaker: Speaker, rng: np.random.Generator, sr: int,
          strict: bool, espeak_installed: bool) -> np.ndarray:
    """Say ``text`` as ``speaker`` at ``sr`` Hz, silence trimmed, not normalized.

    An espeak-ng speaker falls back to its formant voice, with a ``RuntimeWarning``, when
    espeak-ng fails or is not installed, unless ``strict`` (then the ``SoundError`` goes on).
    """
    if speaker.espeak is not None:
        voice, pitch, speed = speaker.espeak
        # A person never says a phrase the same way twice.
        pitch = int(np.clip(pitch + rng.integers(-6, 7), 0, 99))
        speed = int(speed * rng.uniform(0.9, 1.1))
        try:
            if not espeak_installed:
                raise SoundError("espeak-ng is not installed (the espeakng-loader package is missing)")
            return trim_silence(espeak_phrase(text, voice, pitch, speed, sr), sr)
        except SoundError as exc:
            if strict:
                raise
            warnings.warn(f"{exc}; using the formant synthesizer instead", RuntimeWarning,
                          stacklevel=3)
    return trim_silence(formant_speech(text, speaker.formant, rng, sr), sr)


def espeak_phrase(text: str, voice: str, pitch: int, speed: int, sr: int) -> np.ndarray:
    """One phrase from espeak-ng, resampled from its rate to ``sr`` Hz."""
    x, file_sr = espeak.synthesize(text, voice, pitch, speed)
    if x.size == 0 or not np.any(x):
        raise SoundError(f"espeak-ng produced silence for {text!r}")
    ratio = Fraction(sr, int(file_sr))
    return signal.resample_poly(x, ratio.numerator, ratio.denominator)
