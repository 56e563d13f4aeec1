"""acoustic-sim: a simulated humanoid acoustic testbed.

The public API, re-exported here::

    from acoustic_sim import HRTF, BinauralRenderer, room_preset, Microphone, sounds
    hrtf = HRTF.load("kemar")
    room = room_preset("car_cabin")
    renderer = BinauralRenderer(hrtf, room, rng=np.random.default_rng(0))

Conventions (frames, units, clock, errors) are in ``acoustic_sim.frames`` and DESIGN.md.
"""

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.measure import measure_hrtf
from acoustic_sim.acoustics.microphone import FULL_SCALE_PA, Microphone, MicrophoneSpec
from acoustic_sim.acoustics.renderer import BinauralRenderer, Source
from acoustic_sim.acoustics.room import PRESETS, ImageSources, Room, room_preset
from acoustic_sim.acoustics.scene import render_to_wav
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import AcousticSimError, ConfigError, HRTFError, RoomError, SoundError
from acoustic_sim.frames import (
    FRAME_RATE,
    SAMPLE_RATE,
    SPEED_OF_SOUND,
    angle_between_deg,
    frame_end_sample,
    rotation_zyx,
    sph_to_vec,
    vec_to_sph,
)

from acoustic_sim.registration import register_envs

__version__ = "0.1.0"

register_envs()  # the hearing tasks' Gymnasium ids (string entry points: nothing is imported)

__all__ = [
    "AcousticSimError", "BinauralRenderer", "ConfigError", "DirectionGrid", "FRAME_RATE", "FULL_SCALE_PA", "HRTF",
    "HRTFError", "ImageSources", "Microphone", "MicrophoneSpec", "PRESETS", "Room", "RoomError", "SAMPLE_RATE",
    "SPEED_OF_SOUND", "SoundError", "Source", "angle_between_deg", "frame_end_sample", "measure_hrtf", "render_to_wav",
    "room_preset", "rotation_zyx", "sounds", "sph_to_vec", "vec_to_sph",
]
