"""Coordinate frames and the sample clock (acoustic_sim.frames)."""

import math

import numpy as np
import pytest

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import (
    FRAME_RATE,
    SAMPLE_RATE,
    angle_between_deg,
    block_length,
    db_spl_to_pa,
    frame_end_sample,
    head_to_body_azimuth,
    head_to_body_elevation,
    in_lateral_region,
    lateral_deg,
    pa_to_db_spl,
    rotation_zyx,
    sph_to_vec,
    vec_to_sph,
    world_to_head,
)


def test_cardinal_directions():
    np.testing.assert_allclose(sph_to_vec(0, 0), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(sph_to_vec(90, 0), [0, 1, 0], atol=1e-15)  # left is +y
    np.testing.assert_allclose(sph_to_vec(-90, 0), [0, -1, 0], atol=1e-15)
    np.testing.assert_allclose(sph_to_vec(180, 0), [-1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(sph_to_vec(0, 90), [0, 0, 1], atol=1e-15)  # elevation up
    np.testing.assert_allclose(sph_to_vec(0, -30), [np.cos(np.pi / 6), 0, -0.5], atol=1e-15)


def test_vec_to_sph_ranges_and_special_cases():
    az, el = vec_to_sph([[0, 1, 0], [0, -1, 0], [-1, 0, 0], [-1, -0.0, 0], [0, 0, 1], [0, 0, -2]])
    np.testing.assert_allclose(az[:4], [90, -90, 180, 180])  # (-180, 180]: -180 folds to 180
    np.testing.assert_allclose(el, [0, 0, 0, 0, 90, -90])
    az, el = vec_to_sph([3.0, 0, 4.0])  # length does not matter
    assert az == 0 and np.isclose(el, np.rad2deg(np.arctan2(4, 3)))


@pytest.mark.parametrize("bad", [[0, 0, 0], [np.nan, 0, 1], [1, 2]])
def test_vec_to_sph_rejects_bad_vectors(bad):
    with pytest.raises(ConfigError):
        vec_to_sph(bad)


def test_round_trip_grid_including_poles_and_wrap():
    rng = np.random.default_rng(0)
    az = np.concatenate([rng.uniform(-179.999, 180, 500), [180, -90, 90, 0, 179.999]])
    el = np.concatenate([rng.uniform(-89.9, 89.9, 500), [0, 0, 45, -45, 10]])
    az2, el2 = vec_to_sph(sph_to_vec(az, el))
    np.testing.assert_allclose(el2, el, atol=1e-9)
    np.testing.assert_allclose(angle_between_deg(sph_to_vec(az2, el2), sph_to_vec(az, el)), 0, atol=1e-6)
    np.testing.assert_allclose(np.sin(np.deg2rad(az2 - az)), 0, atol=1e-9)
    # Poles: the azimuth is arbitrary, the vector must not be.
    for e in (90, -90):
        v = sph_to_vec([0, 77, -150], e)
        np.testing.assert_allclose(v, np.broadcast_to([0, 0, np.sign(e)], v.shape), atol=1e-12)
        assert np.allclose(vec_to_sph(v)[1], e)
    # Vectors round-trip through angles, too.
    v = rng.normal(size=(300, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    np.testing.assert_allclose(sph_to_vec(*vec_to_sph(v)), v, atol=1e-12)


def test_angle_between():
    x, y, z = np.eye(3)
    assert np.isclose(angle_between_deg(x, y), 90)
    assert np.isclose(angle_between_deg(x, -x), 180)
    assert angle_between_deg(x, x) == 0
    assert np.isclose(angle_between_deg(x, 5 * (x + y)), 45)
    # Accurate for tiny angles, where arccos of the dot product is not.
    tiny = sph_to_vec(1e-6, 0)
    assert np.isclose(angle_between_deg(x, tiny), 1e-6, rtol=1e-6)
    assert angle_between_deg(np.tile(x, (4, 1)), z).shape == (4,)


def test_rotation_maps():
    yaw = rotation_zyx(90, 0, 0)  # turn left: the nose points along world +y
    np.testing.assert_allclose(yaw @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    pitch = rotation_zyx(0, 90, 0)  # positive pitch: nose down
    np.testing.assert_allclose(pitch @ [1, 0, 0], [0, 0, -1], atol=1e-15)
    roll = rotation_zyx(0, 0, 90)  # roll about x: the left ear goes up
    np.testing.assert_allclose(roll @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    r = rotation_zyx(30, -20, 10)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
    assert np.isclose(np.linalg.det(r), 1)
    # world_to_head inverts the pose: a point 2 m along the nose is at head (2, 0, 0).
    head_pos = np.array([1.0, -2.0, 1.5])
    p_world = head_pos + r @ [2.0, 0.0, 0.0]
    np.testing.assert_allclose(world_to_head(p_world, head_pos, r), [2, 0, 0], atol=1e-12)
    # A source 90 deg to the left of a head turned left by 90 deg is behind in the world.
    src = head_pos + rotation_zyx(90) @ sph_to_vec(90, 0)
    np.testing.assert_allclose(src - head_pos, [-1, 0, 0], atol=1e-12)


def test_head_to_body_angles_match_the_rotation():
    """The policies' scalar azimuth and elevation equal vec_to_sph of Rz(yaw) Ry(pitch) v, and
    of the front-back mirror image (-x, y, z) with ``mirror``; to 1e-9 deg."""
    rng = np.random.default_rng(3)
    for _ in range(50):
        v = rng.normal(size=3)
        yaw, pitch, heading = rng.uniform(-math.pi, math.pi), rng.uniform(-0.8, 0.8), rng.uniform(-1.0, 1.0)
        for mirror in (False, True):
            w = v * np.array([-1.0, 1.0, 1.0]) if mirror else v
            az, el = vec_to_sph(rotation_zyx(math.degrees(yaw + heading), math.degrees(pitch)) @ w)
            got_az = math.degrees(head_to_body_azimuth(v, yaw, pitch, heading=heading, mirror=mirror))
            got_el = math.degrees(head_to_body_elevation(v, pitch, mirror=mirror))
            assert abs((got_az - float(az) + 180.0) % 360.0 - 180.0) < 1e-9
            assert got_el == pytest.approx(float(el), abs=1e-9)
    for bad in ([0.0, 0.0, 0.0], [np.nan, 0.0, 1.0], [np.inf, 0.0, 0.0]):
        with pytest.raises(ConfigError, match="no elevation"):
            head_to_body_elevation(bad)


def test_lateral_deg_is_the_angle_to_the_median_plane():
    """The same on the whole cone of confusion (front, back, up), + left; zero is finite."""
    for az, el in ((30.0, 0.0), (150.0, 0.0), (90.0, 60.0)):
        v = sph_to_vec(az, el)
        assert lateral_deg(v) == pytest.approx(math.degrees(math.asin(math.cos(math.radians(el)) * math.sin(math.radians(az)))))
    assert lateral_deg(sph_to_vec(30.0, 0.0)) == pytest.approx(lateral_deg(sph_to_vec(150.0, 0.0))) == pytest.approx(30.0)
    assert lateral_deg([0.0, -2.0, 0.0]) == pytest.approx(-90.0) and lateral_deg([0.0, 0.0, 0.0]) == 0.0


def test_in_lateral_region():
    """The lateral window (either side of the cone of confusion) and the body-frame elevation
    bounds, the head turned 22 deg right (the yaw leaves both unchanged) or pitched."""
    def inside(az, el, pitch=0.0):
        return in_lateral_region(sph_to_vec(az, el), pitch, lateral_range_deg=(5.0, 36.0), elevation_deg=(-90.0, 20.0))

    assert inside(22.0, -10.0) and inside(158.0, -10.0)  # the dashboard speaker and its mirror image
    assert not inside(-22.0, 0.0) and not inside(0.0, 0.0) and not inside(60.0, 0.0)  # right, median plane, too far left
    assert not inside(22.0, 30.0) and inside(22.0, 15.0)  # the elevation bound
    assert not inside(22.0, 15.0, pitch=math.radians(-10.0))  # head nose up 10 deg: 25 deg up in the body's frame
    assert in_lateral_region(sph_to_vec(22.0, 30.0), lateral_range_deg=(5.0, 36.0))  # no bound by default


def test_frame_clock_exact_for_an_hour():
    assert SAMPLE_RATE / FRAME_RATE == 705.6
    k = np.arange(0, int(62.5 * 3600) + 1, dtype=np.int64)
    ends = frame_end_sample(k)
    # Exact reference: round(k * 3528 / 5); the fraction is never .5 so there are no ties.
    expected = (2 * 3528 * k + 5) // 10
    np.testing.assert_array_equal(ends, expected)
    np.testing.assert_array_equal(ends, np.rint(k * 705.6).astype(np.int64))
    assert ends[-1] == 3600 * SAMPLE_RATE  # no drift after one hour
    blocks = np.diff(ends)
    assert set(np.unique(blocks).tolist()) == {705, 706}
    assert abs(blocks.mean() - 705.6) < 1e-5
    assert isinstance(frame_end_sample(5), int) and frame_end_sample(5) == 3528
    assert [block_length(i) for i in range(1, 6)] == list(np.diff(expected[:6]))


def test_levels():
    assert np.isclose(db_spl_to_pa(94.0), 1.0024, rtol=1e-4)  # 94 dB SPL is about 1 Pa
    assert np.isclose(pa_to_db_spl(20e-6), 0.0)
    assert pa_to_db_spl(0.0) == -np.inf  # silence is -inf, never NaN
