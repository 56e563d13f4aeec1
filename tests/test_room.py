"""Rooms, presets, image sources and the late tail."""

import numpy as np
import pytest

from acoustic_sim.acoustics.room import WALLS, Room, eyring_absorption, room_preset
from acoustic_sim.errors import RoomError


def test_presets_have_their_specified_acoustics():
    lab, conf, cabin = room_preset("lab"), room_preset("conference"), room_preset("car_cabin")
    assert 0.27 <= lab.rt60_s <= 0.32 and lab.background_db_spl == 58.0
    assert 0.55 <= conf.rt60_s <= 0.60 and conf.background_db_spl == 35.0
    assert cabin.dimensions == (2.0, 1.5, 1.2) and not cabin.is_frequency_flat
    # Absorptive seats and roof lining: the cabin is much drier above 500 Hz than a bare box.
    assert cabin.rt60_bands()[3] < 0.15
    assert room_preset("anechoic").anechoic
    assert abs(room_preset("shoebox:4x3x2.5", rt60=0.4).rt60_s - 0.4) < 1e-9


def test_eyring_inversion_round_trips():
    a = eyring_absorption(0.5, (5.0, 4.0, 3.0))
    room = Room(name="x", dimensions=(5.0, 4.0, 3.0), absorption={w: (a,) for w in WALLS}, listener=(1, 1, 1))
    assert abs(room.rt60_s - 0.5) < 1e-9


def test_image_sources_come_from_pyroomacoustics_and_move_exactly():
    room = room_preset("lab", ism_order=2)
    s0 = np.array([2.0, 1.5, 1.0])
    images = room.image_sources(s0)
    assert images.positions.shape == (25, 3) and images.orders[0] == 0  # 1 + 6 + 18 images up to order 2
    np.testing.assert_allclose(images.positions[0], s0, atol=1e-6)
    s1 = np.array([4.5, 0.7, 2.2])
    np.testing.assert_allclose(images.at(s1), room.image_sources(s1).positions, atol=1e-5)
    # First-order image in the floor mirrors z.
    assert np.any(np.all(np.isclose(images.positions, [2.0, 1.5, -1.0], atol=1e-5), axis=1))


@pytest.mark.parametrize(
    "name, kwargs, match",
    [
        ("ballroom", {}, "unknown room"),
        ("shoebox:4x3x2.5", {}, "needs --rt60"),
        ("shoebox:4x3x200", {"rt60": 0.5}, "0.5-100 m"),
        ("shoebox:4x3x2.5", {"rt60": 30.0}, "not reachable"),
        ("shoebox:4x3x2.5", {"rt60": -1.0}, "positive"),
        ("anechoic", {"rt60": 0.3}, "no reverberation"),
        ("car_cabin", {"rt60": 0.3}, "do not give rt60"),
    ],
)
def test_bad_rooms_are_clear_errors(name, kwargs, match):
    with pytest.raises(RoomError, match=match):
        room_preset(name, **kwargs)


def test_room_validation():
    good = {w: (0.2,) for w in WALLS}
    with pytest.raises(RoomError, match="dimensions"):
        Room(name="r", dimensions=(0.1, 3, 3), absorption=good)
    with pytest.raises(RoomError, match="absorption"):
        Room(name="r", dimensions=(3, 3, 3), absorption={**good, "floor": (1.0,)}, listener=(1, 1, 1))
    with pytest.raises(RoomError, match="exactly the walls"):
        Room(name="r", dimensions=(3, 3, 3), absorption={"floor": (0.2,)}, listener=(1, 1, 1))
    with pytest.raises(RoomError, match="listener"):
        Room(name="r", dimensions=(3, 3, 3), absorption=good, listener=(4, 1, 1))
