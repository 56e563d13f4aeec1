"""One-shot scenes: a source at a direction from a head in a room, rendered to a WAV.

The glue behind ``acoustic-sim render``: it resolves names (HRTF, room, sound) to
objects, places the source in the head frame and runs the streaming renderer and the
microphone model. Library users compose :class:`BinauralRenderer` directly instead.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import Room, room_preset
from acoustic_sim.acoustics import sounds
from acoustic_sim.errors import ConfigError, SoundError
from acoustic_sim.files import check_writable, write_wav
from acoustic_sim.frames import SAMPLE_RATE, rotation_zyx, sph_to_vec


def resolve_room(room: str | Room, *, rt60: float | None = None) -> Room:
    """A :class:`Room` from a preset name (or the room itself)."""
    return room if isinstance(room, Room) else room_preset(room, rt60=rt60)


def source_signal(sound: str, rng: np.random.Generator, seconds: float) -> np.ndarray:
    """A unit-RMS mono signal for a sound class, ``white_noise`` or a WAV file path."""
    if sound in sounds.available_sounds():
        return sounds.generate(sound, rng, seconds=seconds)
    path = Path(sound)
    if path.suffix.lower() in (".wav", ".flac", ".ogg") or path.exists():
        x = sounds.load_wav(path)
        rms = np.sqrt(np.mean(x**2))
        if rms == 0:
            raise SoundError(f"{path}: the file is silent, so it has no level to scale to")
        return x / rms
    raise SoundError(f"unknown sound {sound!r}; valid: {', '.join(sounds.available_sounds())}, 'impulse' or a WAV file path")


def place_source(listener, head_yaw_deg: float, azimuth_deg: float, elevation_deg: float, distance_m: float) -> np.ndarray:
    """Room position of a source at a direction and distance in the head frame.

    Any finite azimuth is read modulo 360 deg (190 is -170); an elevation outside
    [-90, 90] deg is refused rather than wrapped, as it names no direction unambiguously.
    """
    if not np.isfinite(distance_m) or distance_m <= 0:
        raise ConfigError(f"distance must be positive metres, got {distance_m}")
    if not np.isfinite(azimuth_deg):
        raise ConfigError(f"azimuth must be a finite number of degrees, got {azimuth_deg}")
    if not np.isfinite(elevation_deg) or not -90.0 <= elevation_deg <= 90.0:
        raise ConfigError(f"elevation must be -90..90 degrees, got {elevation_deg}")
    return np.asarray(listener, float) + rotation_zyx(head_yaw_deg) @ sph_to_vec(azimuth_deg, elevation_deg) * distance_m


def render_to_wav(
    *, hrtf, room, rt60=None, listener=None, sound="white_noise", level_db=70.0, azimuth_deg=0.0, elevation_deg=0.0,
    distance_m=1.5, head_yaw_deg=0.0, seconds=1.0, seed=0, out,
) -> dict:
    """Render one source to a 2-channel float32 WAV; returns a summary dict.

    See ``acoustic-sim render --help`` for the meaning of every argument. ``sound`` may be
    ``"impulse"``: the WAV then holds the binaural room impulse response (ear pressure
    per pascal at 1 m), without noise or microphone.
    """
    out = Path(out)
    if out.suffix.lower() != ".wav":
        raise ConfigError(f"--out must be a .wav path, got {out}")
    if not np.isfinite(seconds) or not 0 < seconds <= 3600:
        raise ConfigError(f"seconds must be 0..3600, got {seconds}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    check_writable(out, what="--out")
    rng = np.random.default_rng(seed)
    ears = hrtf if isinstance(hrtf, HRTF) else HRTF.load(hrtf)
    space = resolve_room(room, rt60=rt60)
    head = np.asarray(space.listener if listener is None else listener, float)
    position = place_source(head, head_yaw_deg, azimuth_deg, elevation_deg, distance_m)
    impulse = sound == "impulse"
    renderer = BinauralRenderer(ears, space, rng=rng, background=not impulse)
    renderer.set_head_pose(head, rotation_zyx(head_yaw_deg))
    if impulse:
        audio = renderer.impulse_response(position)
    else:
        signal = source_signal(sound, rng, seconds)
        renderer.add_source("source", signal, position, level_db=level_db, start=0)
        mic = Microphone(rng=rng)
        audio = mic(renderer.render(seconds))
    write_wav(out, audio, SAMPLE_RATE)
    return {
        "out": str(out), "samples": int(audio.shape[1]), "sample_rate": SAMPLE_RATE, "hrtf": ears.name, "room": space.name,
        "rt60_s": round(space.rt60_s, 3) if not space.anechoic else 0.0, "sound": sound,
        "source_position_m": [round(float(v), 4) for v in position], "listener_m": [round(float(v), 4) for v in head],
        "peak": float(np.max(np.abs(audio))) if audio.size else 0.0,
    }
