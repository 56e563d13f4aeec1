"""Named rooms: the anechoic field, the car cabin, the paper's two rooms, any shoebox.

Presets (:func:`room_preset`): ``anechoic``, ``car_cabin``, ``lab``, ``conference`` and
``shoebox:LxWxH`` (with ``rt60``). ``lab`` and ``conference`` are the paper's test room
(RT60 0.27-0.32 s, 58 dB SPL) and HRTF measurement room (RT60 0.55-0.60 s, 35 dB SPL);
their uniform absorption is set by inverting Eyring's formula, the decay that an image
source model with that absorption actually has (pyroomacoustics only inverts Sabine's,
which for these rooms disagrees with the ISM decay by about 20%).
"""

from __future__ import annotations

import re

import numpy as np
import pyroomacoustics as pra

from acoustic_sim.acoustics.room.shoebox import BAND_CENTERS_HZ, WALLS, Room
from acoustic_sim.errors import RoomError
from acoustic_sim.frames import SPEED_OF_SOUND


def eyring_absorption(rt60_s: float, dimensions) -> float:
    """Uniform energy absorption for which Eyring's formula gives ``rt60_s`` in a shoebox."""
    lx, ly, lz = dimensions
    volume, surface = lx * ly * lz, 2 * (lx * ly + lx * lz + ly * lz)
    if not np.isfinite(rt60_s) or rt60_s <= 0:
        raise RoomError(f"rt60 must be a positive number of seconds, got {rt60_s}")
    a = 1.0 - np.exp(-24.0 * np.log(10.0) * volume / (SPEED_OF_SOUND * surface * rt60_s))
    if not 0.005 <= a < 0.99:
        raise RoomError(
            f"rt60 {rt60_s} s is not reachable in a {lx}x{ly}x{lz} m room with realistic walls "
            f"(needs absorption {a:.3f}; valid 0.005-0.99)"
        )
    return float(a)


def _uniform(a: float) -> dict:
    return {w: (a,) for w in WALLS}


PRESETS = ("anechoic", "car_cabin", "lab", "conference", "shoebox:LxWxH")
"""Room names accepted by :func:`room_preset`."""


def room_preset(name: str, *, rt60: float | None = None, ism_order: int | None = None) -> Room:
    """Build a room by name.

    Parameters
    ----------
    name : str
        One of :data:`PRESETS`; ``shoebox:LxWxH`` takes the size in metres, e.g.
        ``shoebox:4x3x2.5``.
    rt60 : float, optional
        Target RT60 in seconds (0.05-5): required for ``shoebox``, optional for ``lab`` and
        ``conference`` (overrides the paper's value), refused for the others.
    ism_order : int, optional
        Image-source order rendered through the HRTF (default per preset).
    """
    if name == "anechoic":
        if rt60 is not None:
            raise RoomError("the anechoic room has no reverberation: do not give rt60")
        return Room(name="anechoic", anechoic=True, ism_order=0, background_db_spl=0.0, listener=(0.0, 0.0, 0.0))
    if name == "car_cabin":
        if rt60 is not None:
            raise RoomError("car_cabin's reverberation follows from its materials: do not give rt60")
        # Interior of a compact car: x forward, y to the left, z up. Windows and windscreen
        # are glass; seats (the rear wall and the floor side as seen from the front) are
        # upholstered cloth; the roof lining is a felt-backed headliner; the floor carpeted.
        absorption = {
            "west": pra.materials_data["absorption"]["Seating (2 seats per m2)"]["chairs_upholstered_cloth"]["coeffs"],
            "east": pra.materials_data["absorption"]["Glazing"]["glass_window"]["coeffs"],
            "south": pra.materials_data["absorption"]["Glazing"]["glass_window"]["coeffs"],
            "north": pra.materials_data["absorption"]["Glazing"]["glass_window"]["coeffs"],
            "floor": pra.materials_data["absorption"]["Floor coverings"]["carpet_cotton"]["coeffs"],
            "ceiling": pra.materials_data["absorption"]["Floor coverings"]["felt_5mm"]["coeffs"],
        }
        absorption = {w: tuple(_seven(c)) for w, c in absorption.items()}
        return Room(
            name="car_cabin", dimensions=(2.0, 1.5, 1.2), absorption=absorption, background_db_spl=40.0,
            ism_order=3 if ism_order is None else ism_order, listener=(0.75, 1.05, 0.85),
        )
    if name in ("lab", "conference"):
        dims, target, noise, listener = (
            ((6.0, 5.0, 3.0), 0.30, 58.0, (3.0, 2.5, 1.2)) if name == "lab"
            else ((8.0, 6.0, 3.0), 0.575, 35.0, (4.0, 3.0, 1.2))
        )
        t = target if rt60 is None else rt60
        return Room(
            name=name, dimensions=dims, absorption=_uniform(eyring_absorption(t, dims)), background_db_spl=noise,
            ism_order=3 if ism_order is None else ism_order, listener=listener, target_rt60_s=t,
        )
    m = re.fullmatch(r"shoebox:([0-9.]+)x([0-9.]+)x([0-9.]+)", name)
    if m:
        try:
            dims = tuple(float(v) for v in m.groups())
        except ValueError:
            raise RoomError(f"room {name!r}: dimensions must be numbers, e.g. shoebox:4x3x2.5") from None
        if rt60 is None:
            raise RoomError(f"room {name!r} needs --rt60 (seconds)")
        if any(not 0.5 <= d <= 100 for d in dims):
            raise RoomError(f"room {name!r}: each dimension must be 0.5-100 m")
        return Room(
            name=name, dimensions=dims, absorption=_uniform(eyring_absorption(rt60, dims)), background_db_spl=35.0,
            ism_order=3 if ism_order is None else ism_order, listener=tuple(d / 2 for d in dims), target_rt60_s=rt60,
        )
    raise RoomError(f"unknown room {name!r}; valid: {', '.join(PRESETS)}")


def _seven(coeffs) -> list[float]:
    """Pad a material's coefficient list to the 7 bands (repeat the last band)."""
    c = list(coeffs)[: len(BAND_CENTERS_HZ)]
    return c + [c[-1]] * (len(BAND_CENTERS_HZ) - len(c))
