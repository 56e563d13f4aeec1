"""Direction grids (acoustic_sim.directions)."""

import dataclasses

import numpy as np
import pytest

from acoustic_sim.directions import (
    DirectionGrid,
    angular_error_deg,
    horizontal_plane,
    is_front,
    is_left,
    is_up,
    median_plane,
)
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import sph_to_vec


def test_paper_grid_size_and_spacing():
    grid = DirectionGrid.paper()
    nn = grid.nearest_neighbour_angles_deg()
    print(f"\npaper grid: D={len(grid)}, nearest neighbour min {nn.min():.2f} / median "
          f"{np.median(nn):.2f} / max {nn.max():.2f} deg, elevation "
          f"{grid.elevation_deg.min():.0f}..{grid.elevation_deg.max():.0f} deg, ident {grid.ident}")
    assert 300 <= len(grid) <= 350
    assert len(grid) == 327
    assert np.mean((nn >= 9.0) & (nn <= 13.0)) >= 0.95
    assert np.mean((nn >= 9.9) & (nn <= 11.8)) == 1.0  # the paper's 10-11.8 deg
    # Restricted to the KEMAR coverage.
    assert grid.elevation_deg.min() >= -40 - 1e-9 and grid.elevation_deg.max() <= 90 + 1e-9
    assert np.isclose(grid.elevation_deg.min(), -40) and np.isclose(grid.elevation_deg.max(), 90)
    # Every ring is evenly spread: the grid is left/right balanced.
    assert abs(np.sum(grid.vectors[:, 1])) < 1e-9


def test_paper_grid_follows_hrtf_coverage():
    class Coverage:
        min_elevation_deg = -90.0
        max_elevation_deg = 90.0

    full = DirectionGrid.paper(Coverage())
    nn = full.nearest_neighbour_angles_deg()
    assert len(full) > len(DirectionGrid.paper()) and np.isclose(full.elevation_deg.min(), -90)
    assert np.mean((nn >= 9.0) & (nn <= 13.0)) >= 0.95
    upper = DirectionGrid.paper(min_elevation_deg=0.0)
    assert upper.elevation_deg.min() >= -1e-9
    with pytest.raises(ConfigError):
        DirectionGrid.paper(min_elevation_deg=30, max_elevation_deg=-30)
    with pytest.raises(ConfigError):
        DirectionGrid.paper(spacing_deg=0)


def test_ident_and_immutability():
    a, b = DirectionGrid.paper(), DirectionGrid.paper()
    assert a.ident == b.ident and len(a.ident) == 16
    assert a.ident != DirectionGrid.paper(azimuth_spacing_deg=11.5).ident
    assert DirectionGrid.from_vectors(a.vectors * 3.0).ident == a.ident  # normalized
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.name = "other"
    with pytest.raises(ValueError):
        a.vectors[0, 0] = 1.0
    with pytest.raises(ConfigError):
        DirectionGrid.from_vectors([[0, 0, 0], [1, 0, 0]])
    with pytest.raises(ConfigError):
        DirectionGrid.from_vectors(np.zeros((0, 3)))


def test_horizontal_plane():
    grid = horizontal_plane(10)
    assert len(grid) == 36
    np.testing.assert_allclose(grid.elevation_deg, 0, atol=1e-12)
    np.testing.assert_allclose(grid.vectors[:, 2], 0, atol=1e-12)
    np.testing.assert_allclose(np.diff(np.unwrap(np.deg2rad(grid.azimuth_deg))), np.deg2rad(10))
    np.testing.assert_allclose(grid.vectors[0], [1, 0, 0])
    np.testing.assert_allclose(grid.vectors[9], [0, 1, 0], atol=1e-12)  # 90 deg = left
    assert len(DirectionGrid.horizontal_plane(5)) == 72


def test_median_plane():
    grid = median_plane(10, -40, 90)
    np.testing.assert_allclose(grid.vectors[:, 1], 0, atol=1e-12)
    assert len(grid) == 27  # psi = -40 .. 220 in 10 deg steps
    np.testing.assert_allclose(grid.vectors[0], sph_to_vec(0, -40), atol=1e-12)
    np.testing.assert_allclose(grid.vectors[13], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(grid.vectors[-1], sph_to_vec(180, -40), atol=1e-12)
    front = grid.vectors[:, 0] > 1e-9
    np.testing.assert_allclose(grid.azimuth_deg[front], 0)
    np.testing.assert_allclose(np.abs(grid.azimuth_deg[grid.vectors[:, 0] < -1e-9]), 180)
    # Consecutive directions are one step apart: the polar angle runs over the top.
    np.testing.assert_allclose(angular_error_deg(grid.vectors[:-1], grid.vectors[1:]), 10)
    capped = median_plane(10, -40, 60)
    assert capped.elevation_deg.max() <= 60 + 1e-9 and len(capped) == 27 - 5


def test_nearest_and_angular_error():
    grid = DirectionGrid.paper()
    np.testing.assert_array_equal(grid.nearest(grid.vectors), np.arange(len(grid)))
    rng = np.random.default_rng(1)
    v = rng.normal(size=(200, 3))
    idx = grid.nearest(v)
    err = angular_error_deg(v, grid.vectors[idx])
    brute = angular_error_deg(v[:, None, :], grid.vectors[None]).min(axis=1)
    np.testing.assert_allclose(err, brute, atol=1e-9)
    assert grid.nearest(v.reshape(10, 20, 3)).shape == (10, 20)
    x, y, _ = np.eye(3)
    assert np.isclose(angular_error_deg(x, y), 90)
    assert np.isclose(angular_error_deg(x, -x), 180)
    assert np.isclose(angular_error_deg(sph_to_vec(10, 0), sph_to_vec(-10, 0)), 20)
    assert np.isclose(angular_error_deg(sph_to_vec(0, 30), sph_to_vec(180, 30)), 120)
    np.testing.assert_allclose(angular_error_deg(x, [[1, 1, 0], [0, 0, 3]]), [45, 90])


def test_hemisphere_helpers():
    v = sph_to_vec([90, -90, 0, 180, 30, -150], [0, 0, 60, -60, 10, -10])
    np.testing.assert_array_equal(is_left(v), [True, False, False, False, True, False])
    np.testing.assert_array_equal(is_front(v), [False, False, True, False, True, False])
    np.testing.assert_array_equal(is_up(v), [False, False, True, False, True, False])
