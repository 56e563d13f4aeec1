"""The shoebox room: geometry, wall materials, background level, Eyring decay.

A :class:`Room` is a shoebox (x from 0 to L, y from 0 to W, z from 0 to H, metres, in the
room's own frame, z up) with one material per wall (energy absorption per octave band,
from pyroomacoustics' material database), a background noise level and the image-source
order up to which reflections are rendered through the HRTF of their direction
(:mod:`~acoustic_sim.acoustics.room.image_sources`); later reflections are the diffuse
tail's (:mod:`~acoustic_sim.acoustics.room.diffuse_tail`).
"""

from __future__ import annotations

import dataclasses
from functools import cached_property

import numpy as np
import pyroomacoustics as pra

from acoustic_sim.acoustics.room.image_sources import ImageSources
from acoustic_sim.errors import RoomError
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND

WALLS = ("west", "east", "south", "north", "floor", "ceiling")
"""Wall names in pyroomacoustics' order: x=0, x=L, y=0, y=W, z=0, z=H."""

BAND_CENTERS_HZ = (125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0)
"""Octave-band centre frequencies (Hz) of the absorption coefficients."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class Room:
    """A shoebox room (or free field) for the acoustic world.

    Parameters
    ----------
    name : str
        Preset or user name, used in file names and reports.
    dimensions : tuple of 3 float
        Interior size (L, W, H) in metres along the room's x, y, z; each 0.5-100 m.
        Ignored when ``anechoic``.
    absorption : dict of str to tuple of float
        Energy absorption coefficient (0 <= a < 1) per wall in :data:`WALLS`, one value per
        octave band of :data:`BAND_CENTERS_HZ` (or a single value for all bands).
    background_db_spl : float
        Background noise level at the ears in dB SPL (unweighted), 0-120.
    ism_order : int
        Highest image-source order rendered through the HRTF (0-12); later reflections are
        in the diffuse tail.
    anechoic : bool
        Free field: no reflections and no tail.
    listener : tuple of 3 float
        Default head-centre position (m, room frame) used by the CLI.
    target_rt60_s : float or None
        The RT60 (s) the preset was designed for, for reporting and tests.
    """

    name: str
    dimensions: tuple[float, float, float] = (1.0, 1.0, 1.0)
    absorption: dict = dataclasses.field(default_factory=dict)
    background_db_spl: float = 0.0
    ism_order: int = 3
    anechoic: bool = False
    listener: tuple[float, float, float] = (0.5, 0.5, 0.5)
    target_rt60_s: float | None = None

    def __post_init__(self) -> None:
        if not 0.0 <= self.background_db_spl <= 120.0:
            raise RoomError(f"room {self.name!r}: background_db_spl must be 0..120 dB, got {self.background_db_spl}")
        if not isinstance(self.ism_order, (int, np.integer)) or not 0 <= self.ism_order <= 12:
            raise RoomError(f"room {self.name!r}: ism_order must be an integer 0..12, got {self.ism_order!r}")
        if self.anechoic:
            return
        dims = np.asarray(self.dimensions, dtype=float)
        if dims.shape != (3,) or not np.all(np.isfinite(dims)) or np.any(dims < 0.5) or np.any(dims > 100):
            raise RoomError(f"room {self.name!r}: dimensions must be 3 lengths of 0.5-100 m, got {self.dimensions}")
        if set(self.absorption) != set(WALLS):
            raise RoomError(f"room {self.name!r}: absorption needs exactly the walls {WALLS}, got {sorted(self.absorption)}")
        for wall, coeffs in self.absorption.items():
            a = np.atleast_1d(np.asarray(coeffs, dtype=float))
            if a.size not in (1, len(BAND_CENTERS_HZ)) or np.any(~np.isfinite(a)) or np.any(a < 0) or np.any(a >= 1):
                raise RoomError(
                    f"room {self.name!r}: wall {wall!r} absorption must be 1 or {len(BAND_CENTERS_HZ)} values in [0, 1), got {coeffs}"
                )
        self.check_inside(self.listener, what="listener")

    # -- geometry -------------------------------------------------------------------------
    @property
    def volume_m3(self) -> float:
        """Interior volume in m^3 (inf for free field)."""
        return float(np.prod(self.dimensions)) if not self.anechoic else float("inf")

    @property
    def surface_m2(self) -> float:
        """Interior surface in m^2."""
        lx, ly, lz = self.dimensions
        return 2.0 * (lx * ly + lx * lz + ly * lz)

    def wall_areas(self) -> np.ndarray:
        """Areas (m^2) of the walls in :data:`WALLS` order."""
        lx, ly, lz = self.dimensions
        return np.array([ly * lz, ly * lz, lx * lz, lx * lz, lx * ly, lx * ly])

    def check_inside(self, position, *, what: str = "position", margin: float = 0.05) -> np.ndarray:
        """Return ``position`` as an array, or raise :class:`RoomError` if it is outside the room.

        ``margin`` (m) keeps points off the walls, where image sources would coincide.
        """
        p = np.asarray(position, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise RoomError(f"{what} must be 3 finite coordinates in metres, got {position}")
        if not self.anechoic and (np.any(p < margin) or np.any(p > np.asarray(self.dimensions) - margin)):
            raise RoomError(
                f"{what} {tuple(round(float(v), 3) for v in p)} is not inside room {self.name!r} of size {self.dimensions} m "
                f"(at least {margin} m from every wall)"
            )
        return p

    # -- acoustics ------------------------------------------------------------------------
    def absorption_bands(self) -> np.ndarray:
        """Energy absorption per wall and octave band, shape (6, 7)."""
        n = len(BAND_CENTERS_HZ)
        return np.stack([np.broadcast_to(np.atleast_1d(np.asarray(self.absorption[w], float)), (n,)) for w in WALLS])

    def rt60_bands(self) -> np.ndarray:
        """Eyring reverberation time (s) per octave band, shape (7,): the decay of this
        room's image sources, which the late tail continues. Free field gives zeros."""
        if self.anechoic:
            return np.zeros(len(BAND_CENTERS_HZ))
        mean_a = (self.wall_areas()[:, None] * self.absorption_bands()).sum(0) / self.surface_m2
        return 24.0 * np.log(10.0) * self.volume_m3 / (SPEED_OF_SOUND * -self.surface_m2 * np.log1p(-mean_a))

    @property
    def rt60_s(self) -> float:
        """Mean of the 500 Hz and 1 kHz Eyring RT60 in seconds (the usual single figure)."""
        t = self.rt60_bands()
        return float(0.5 * (t[2] + t[3]))

    def pra_room(self, *, max_order: int | None = None, fs: int = SAMPLE_RATE) -> pra.ShoeBox:
        """A pyroomacoustics ShoeBox with this room's geometry and materials (no air absorption)."""
        if self.anechoic:
            raise RoomError(f"room {self.name!r} is anechoic: it has no pyroomacoustics shoebox")
        bands = self.absorption_bands()
        materials = {
            wall: pra.Material({"coeffs": [float(a) for a in bands[i]], "center_freqs": list(BAND_CENTERS_HZ)})
            for i, wall in enumerate(WALLS)
        }
        return pra.ShoeBox(
            list(self.dimensions), fs=fs, materials=materials,
            max_order=self.ism_order if max_order is None else max_order, air_absorption=False,
        )

    @cached_property
    def is_frequency_flat(self) -> bool:
        """True when every wall absorbs all bands equally (one gain per image suffices)."""
        a = self.absorption_bands()
        return bool(np.allclose(a, a[:, :1]))

    def image_sources(self, source_position, *, max_order: int | None = None) -> "ImageSources":
        """Image sources of a source at ``source_position`` (m, room frame), from pyroomacoustics."""
        return ImageSources.compute(self, source_position, max_order=max_order)
