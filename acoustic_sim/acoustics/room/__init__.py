"""Rooms: shoebox geometry and materials, image sources, the late tail, named presets.

- :mod:`.shoebox`: :class:`Room`, the walls (:data:`WALLS`) and octave bands
  (:data:`BAND_CENTERS_HZ`), its Eyring decay and its pyroomacoustics shoebox;
- :mod:`.image_sources`: :class:`ImageSources`, the early reflections of one source;
- :mod:`.diffuse_tail`: :func:`late_tail` and the fill that splices it to the images;
- :mod:`.room_presets`: :func:`room_preset` and :func:`eyring_absorption`.
"""

from acoustic_sim.acoustics.room.image_sources import ImageSources
from acoustic_sim.acoustics.room.shoebox import BAND_CENTERS_HZ, WALLS, Room
from acoustic_sim.acoustics.room.diffuse_tail import late_tail, tail_complete_sample, tail_fill, tail_length
from acoustic_sim.acoustics.room.room_presets import PRESETS, eyring_absorption, room_preset

__all__ = [
    "BAND_CENTERS_HZ", "PRESETS", "WALLS", "ImageSources", "Room", "eyring_absorption", "late_tail",
    "room_preset", "tail_complete_sample", "tail_fill", "tail_length",
]
