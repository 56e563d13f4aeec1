"""Binaural room impulse responses for the sound data: a bank per room, for random positions.

Step 1 of a scene (:mod:`~acoustic_sim.auditory.sound_data.scene_mix`): convolving with a
bank is exactly what the streaming renderer does for a static head and source, at a
fraction of its cost.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory.sound_data.data_types import ROOMS, _progress
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import sph_to_vec


class BRIRBank:
    """Binaural room impulse responses for random source positions, per room.

    Parameters
    ----------
    brirs : dict of str to list of numpy.ndarray
        Per room name, BRIRs of shape (2, L) (left, right): eardrum pressure (Pa) per unit
        pressure at 1 m from the source.
    """

    def __init__(self, brirs: dict[str, list[np.ndarray]]) -> None:
        if not brirs or any(len(v) == 0 for v in brirs.values()):
            raise ConfigError("a BRIR bank needs at least one BRIR per room")
        self.brirs = brirs

    @classmethod
    def build(cls, rng: np.random.Generator, *, rooms=ROOMS, per_room: int = 8, hrtf=None,
              distance_m=(0.5, 3.0), elevation_deg=(-30.0, 60.0), progress: bool = False) -> BRIRBank:
        """Render BRIRs for ``per_room`` random positions in each room.

        Parameters
        ----------
        rng : numpy.random.Generator
            Draws the positions and the rooms' diffuse tails.
        rooms : sequence of str
            Room presets.
        per_room : int
            BRIRs per room, >= 1 (each takes about 0.3-0.6 s to render).
        hrtf : acoustic_sim.acoustics.hrtf.HRTF, optional
            The ears; default the bundled KEMAR.
        distance_m : tuple of float
            Range of source distances from the head centre (m); positions are pulled in to
            stay 0.1 m inside the walls (and at least 0.3 m from the head).
        elevation_deg : tuple of float
            Range of source elevations (deg, head frame); azimuth is uniform.
        progress : bool
            Show a progress bar.
        """
        from acoustic_sim.acoustics.hrtf import HRTF

        if per_room < 1:
            raise ConfigError(f"per_room must be >= 1, got {per_room}")
        hrtf = HRTF.load("kemar") if hrtf is None else hrtf
        jobs = [(r, i) for r in rooms for i in range(per_room)]
        bar = _progress(len(jobs), "BRIR bank", progress)
        out: dict[str, list[np.ndarray]] = {}
        for name in rooms:
            room = room_preset(name)
            renderer = BinauralRenderer(hrtf, room, rng=rng)
            head = np.asarray(room.listener, float)
            out[name] = []
            for _ in range(per_room):
                pos = _random_position(room, head, rng, distance_m, elevation_deg)
                out[name].append(renderer.impulse_response(pos))
                bar.update(1)
        bar.close()
        return cls(out)


def _random_position(room, head, rng, distance_m, elevation_deg) -> np.ndarray:
    for _ in range(1000):
        v = sph_to_vec(rng.uniform(-180.0, 180.0), rng.uniform(*elevation_deg))
        r = rng.uniform(*distance_m)
        if room.anechoic:
            return head + r * v
        # Largest distance along v that keeps 0.1 m from every wall.
        dims = np.asarray(room.dimensions, float)
        with np.errstate(divide="ignore"):
            t_hi = np.where(v > 0, (dims - 0.1 - head) / v, np.where(v < 0, (0.1 - head) / v, np.inf))
        reach = float(np.min(t_hi))
        if reach >= 0.3:
            return head + min(r, reach) * v
    raise ConfigError(f"room {room.name!r}: no source position 0.3 m from the head fits inside")
