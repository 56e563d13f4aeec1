"""The acoustic room's frame in the world: a box with its origin at a corner.

The one conversion between MuJoCo's world and the room coordinates of the acoustic model
(pyroomacoustics' shoebox: origin at a corner, axes the box's); the coupling and the scene
builder both use it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from acoustic_sim.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class RoomFrame:
    """The acoustic room's frame in the world: a box with its origin at a corner.

    Attributes
    ----------
    origin : numpy.ndarray, shape (3,)
        World position (m) of the room's corner (0, 0, 0).
    rotation : numpy.ndarray, shape (3, 3)
        Room to world rotation (columns: the room's axes in world coordinates).
    dimensions : numpy.ndarray, shape (3,)
        Room size (m) along its x, y, z.
    """

    origin: np.ndarray
    rotation: np.ndarray
    dimensions: np.ndarray

    @classmethod
    def from_box(cls, centre, rotation, half_sizes) -> RoomFrame:
        """The frame of a box given by its centre (m, world), orientation (box to world)
        and half-sizes (m)."""
        c = np.asarray(centre, dtype=float)
        r = np.asarray(rotation, dtype=float)
        h = np.asarray(half_sizes, dtype=float)
        if c.shape != (3,) or r.shape != (3, 3) or h.shape != (3,) or np.any(h <= 0):
            raise ConfigError(f"a room box needs a centre (3,), a rotation (3, 3) and positive half-sizes (3,), got {h}")
        return cls(origin=c - r @ h, rotation=r, dimensions=2.0 * h)

    def to_room(self, points) -> np.ndarray:
        """World points (..., 3) in room coordinates (m)."""
        return (np.asarray(points, dtype=float) - self.origin) @ self.rotation

    def to_world(self, points) -> np.ndarray:
        """Room points (..., 3) in world coordinates (m)."""
        return np.asarray(points, dtype=float) @ self.rotation.T + self.origin

    def rotation_to_room(self, rotation) -> np.ndarray:
        """A world orientation (3x3, frame to world) as frame to room."""
        return self.rotation.T @ np.asarray(rotation, dtype=float)

    def entry_point(self, point_room, listener_room, margin: float) -> np.ndarray:
        """Where the straight path from ``point_room`` (outside) to ``listener_room`` enters
        the room, taken ``margin`` (m) inside its walls: the box shrunk by ``margin`` cut by
        the segment from the listener (clipped into that box) to the point. A point inside
        that box is its own entry point."""
        p = np.asarray(point_room, dtype=float)
        lo, hi = margin, self.dimensions - margin
        h = np.clip(np.asarray(listener_room, dtype=float), lo, hi)
        d = p - h
        t = 1.0
        for k in range(3):
            if d[k] > 0.0:
                t = min(t, (hi[k] - h[k]) / d[k])
            elif d[k] < 0.0:
                t = min(t, (lo - h[k]) / d[k])
        return h + max(t, 0.0) * d
