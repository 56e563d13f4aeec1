"""The world-frame direction tracker: a head turn resolves the front-back mirror image."""

import numpy as np
import pytest

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.auditory.tracker import DirectionTracker
from acoustic_sim.directions import DirectionGrid, angular_error_deg
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import rotation_zyx, sph_to_vec


@pytest.fixture(scope="module")
def grid():
    return DirectionGrid.paper(HRTF.load("kemar"))


def ambiguous_map(grid, head_vector, kappa=20.0):
    """A head-frame existence map with equal peaks at a direction and its front-back mirror
    image: what interaural cues alone give."""
    h = np.asarray(head_vector, float)
    m = h * np.array([-1.0, 1.0, 1.0])
    return np.exp(kappa * (grid.vectors @ h - 1)) + np.exp(kappa * (grid.vectors @ m - 1))


def feed(tracker, grid, world, yaws_deg, name="s", dt=0.016):
    for i, yaw in enumerate(yaws_deg):
        r = rotation_zyx(yaw)
        tracker.note_pose(i * dt, r)
        tracker.add(name, i * dt, ambiguous_map(grid, r.T @ world))


@pytest.mark.parametrize("azimuth", [150.0, -120.0, 30.0, -20.0])
def test_a_turn_finds_the_true_side_of_an_ambiguous_source(grid, azimuth):
    world = sph_to_vec(azimuth, 0.0)
    still = DirectionTracker(grid, ("s",), fold=1.0)
    feed(still, grid, world, [0.0] * 40)
    est = still.estimate("s")
    assert not est.decided  # the mirror image is as likely as the source
    assert abs(est.margin_nats) < 1e-6

    turned = DirectionTracker(grid, ("s",), fold=1.0)
    feed(turned, grid, world, list(np.linspace(0.0, 30.0, 20)) + [30.0] * 20)
    est = turned.estimate("s")
    assert est.decided and est.margin_nats >= turned.decide_nats
    assert float(angular_error_deg(est.world_vector, world)) < 8.0  # the grid's spacing is 10.8 deg
    head_truth = rotation_zyx(30.0).T @ world
    assert est.front == bool(head_truth[0] >= 0)
    np.testing.assert_allclose(est.head_vector, rotation_zyx(30.0).T @ est.world_vector, atol=1e-12)


def test_static_evidence_keeps_the_head_frame_peak(grid):
    """Without motion and without folding, the world peak is the head peak turned into the world."""
    t = DirectionTracker(grid, ("s",), fold=0.0)
    r = rotation_zyx(40.0)
    head = sph_to_vec(-60.0, 20.0)
    t.note_pose(0.0, r)
    p = np.exp(15.0 * (grid.vectors @ head - 1))
    for i in range(5):
        t.add("s", 0.01 * i, p)
    est = t.estimate("s")
    k = int(np.argmax(p))
    assert float(angular_error_deg(est.world_vector, r @ grid.vectors[k])) < 8.0
    assert est.frames == 5


def test_a_source_on_the_interaural_axis_needs_no_front_back_decision(grid):
    t = DirectionTracker(grid, ("s",), fold=1.0)
    feed(t, grid, sph_to_vec(90.0, 0.0), [0.0] * 5)
    assert t.estimate("s").decided and t.estimate("s").margin_nats == np.inf


def test_weight_sets_how_fast_evidence_decides(grid):
    world = sph_to_vec(140.0, 0.0)
    yaws = list(np.linspace(0.0, 20.0, 12))
    strong, weak = DirectionTracker(grid, ("s",), weight=1.0), DirectionTracker(grid, ("s",), weight=0.1)
    feed(strong, grid, world, yaws)
    feed(weak, grid, world, yaws)
    assert strong.estimate("s").margin_nats == pytest.approx(10 * weak.estimate("s").margin_nats, rel=1e-9)


def test_reset_forgets_and_flat_maps_are_no_evidence(grid):
    t = DirectionTracker(grid, ("a", "b"))
    feed(t, grid, sph_to_vec(10.0, 0.0), [0.0] * 3, name="a")
    t.add("b", 1.0, np.zeros(len(grid)))
    assert t.frames("a") == 3 and t.frames("b") == 0 and t.estimate("b") is None
    t.reset()
    assert t.frames("a") == 0 and t.estimate("a") is None
    np.testing.assert_array_equal(t.rotation_at(0.0), np.eye(3))  # no pose: a still head, the world's frame


def test_the_pose_in_force_is_the_latest_at_or_before_the_frame(grid):
    t = DirectionTracker(grid)
    t.note_pose(0.0, rotation_zyx(0.0))
    t.note_pose(0.5, rotation_zyx(30.0))
    np.testing.assert_allclose(t.rotation_at(0.49), rotation_zyx(0.0))
    np.testing.assert_allclose(t.rotation_at(0.5), rotation_zyx(30.0))
    np.testing.assert_allclose(t.rotation_at(-1.0), rotation_zyx(0.0))  # before the first: the earliest


def test_bad_input_is_refused(grid):
    t = DirectionTracker(grid, ("a",))
    t.note_pose(1.0, np.eye(3))
    with pytest.raises(ConfigError, match="must not decrease"):
        t.note_pose(0.5, np.eye(3))
    with pytest.raises(ConfigError, match="orthonormal"):
        t.note_pose(2.0, 2 * np.eye(3))
    with pytest.raises(ConfigError, match="3, 3"):
        t.note_pose(2.0, np.eye(2))
    with pytest.raises(ConfigError, match="unknown class"):
        t.add("b", 1.0, np.ones(len(grid)))
    with pytest.raises(ConfigError, match="shape"):
        t.add("a", 1.0, np.ones(3))
    for kw in ({"outlier": 0.0}, {"fold": 1.5}, {"decide_nats": 0.0}, {"weight": 2.0}, {"half_life_s": -1.0}):
        with pytest.raises(ConfigError):
            DirectionTracker(grid, **kw)


def test_half_life_lets_a_moved_source_take_over(grid):
    t = DirectionTracker(grid, ("s",), fold=0.0, half_life_s=0.2)
    t.note_pose(0.0, np.eye(3))
    old, new = sph_to_vec(60.0, 0.0), sph_to_vec(-60.0, 0.0)
    for i in range(50):
        t.add("s", 0.016 * i, np.exp(15.0 * (grid.vectors @ old - 1)))
    for i in range(50, 80):
        t.add("s", 0.016 * i, np.exp(15.0 * (grid.vectors @ new - 1)))
    assert float(angular_error_deg(t.estimate("s").world_vector, new)) < 8.0
