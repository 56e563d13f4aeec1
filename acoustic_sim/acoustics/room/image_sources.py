"""Image sources of a source in a shoebox, from pyroomacoustics, movable with the source.

Image sources come from pyroomacoustics (``ShoeBox.image_source_model``); nothing here
re-implements the ISM. Because a shoebox's image positions are affine in the source
position (each image mirrors every axis an even or odd number of times), the images of a
moving source are updated from one pyroomacoustics run by :meth:`ImageSources.at`, which
is exact for a shoebox and costs microseconds instead of a new room.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from acoustic_sim.errors import RoomError

if TYPE_CHECKING:
    from acoustic_sim.acoustics.room.shoebox import Room


@dataclasses.dataclass(frozen=True)
class ImageSources:
    """Image sources of one source in a shoebox, movable with the source.

    Attributes
    ----------
    positions : numpy.ndarray, shape (M, 3)
        Image positions in metres (room frame) for ``source_position``; row 0 is the source.
    parity : numpy.ndarray, shape (M, 3)
        +1 or -1 per axis: how an image moves when the source moves.
    damping : numpy.ndarray, shape (B, M)
        Product of the wall pressure reflection coefficients per octave band (B = 1 for a
        frequency-flat room), as pyroomacoustics computes it.
    orders : numpy.ndarray, shape (M,)
        Reflection order of each image.
    source_position : numpy.ndarray, shape (3,)
    """

    positions: np.ndarray
    parity: np.ndarray
    damping: np.ndarray
    orders: np.ndarray
    source_position: np.ndarray

    @classmethod
    def compute(cls, room: Room, source_position, *, max_order: int | None = None) -> "ImageSources":
        s = room.check_inside(source_position, what="source position")
        if room.anechoic:
            return cls(s[None, :].copy(), np.ones((1, 3)), np.ones((1, 1)), np.zeros(1, int), s)
        order = room.ism_order if max_order is None else max_order

        def run(pos):
            r = room.pra_room(max_order=order)
            r.add_source(list(pos))
            # pyroomacoustics needs a microphone to run its visibility test (all images of
            # a shoebox are visible from anywhere inside it).
            r.add_microphone(list(np.asarray(room.dimensions) / 2.0))
            r.image_source_model()
            src = r.sources[0]
            return src.images.T.copy(), src.damping.copy(), src.orders.copy()

        images, damping, orders = run(s)
        # A second run with the source nudged tells each image's mirror parity per axis;
        # pyroomacoustics enumerates images in the same order for any position in the box.
        delta = 1e-3
        nudged = s + delta * np.where(s + delta < np.asarray(room.dimensions) - 0.01, 1.0, -1.0)
        images2, _, _ = run(nudged)
        parity = np.sign(np.round((images2 - images) / (nudged - s)))
        if images.shape[0] != images2.shape[0] or np.any(parity == 0):
            raise RoomError("pyroomacoustics returned inconsistent image sources for a nudged source")
        if room.is_frequency_flat:
            damping = damping[:1]
        # Row 0 must be the direct path (order 0).
        first = int(np.argmin(orders))
        perm = np.r_[first, np.delete(np.arange(len(orders)), first)]
        return cls(images[perm], parity[perm], damping[:, perm], orders[perm], s)

    def at(self, source_position) -> np.ndarray:
        """Image positions (M, 3) for the source moved to ``source_position`` (exact for a shoebox)."""
        return self.positions + self.parity * (np.asarray(source_position, float) - self.source_position)
