"""Direction grids: the paper's ~326 estimation directions, the horizontal and median planes.

A :class:`DirectionGrid` is an ordered, immutable set of unit vectors in the head frame of
:mod:`acoustic_sim.frames` (x forward, y left, z up). SSDENet outputs one existence value
per grid direction, so a model checkpoint stores the grid's :attr:`DirectionGrid.ident` and
refuses to run on another grid.

The paper's grid (Omura et al. 2022: "326 directions around the dummy head ... the angle
between each direction and the nearest direction is 10 deg ~ 11.8 deg") is rebuilt here as
elevation rings (:meth:`DirectionGrid.paper`): rings every 10 deg of elevation counted down
from the zenith, each ring holding ``round(360 cos(el) / 10.8)`` equally spaced azimuths
(at least one), odd rings rotated by half a step. Restricted to the KEMAR coverage
(-40..90 deg) this gives 327 directions whose nearest neighbours are 9.96-11.0 deg away
(the 9.96 deg are the six directions of the 80 deg ring); 10.8 deg is the azimuth spacing
that comes closest to 326 (10.76 gives 328, 10.82 gives 325).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import angle_between_deg, sph_to_vec, unit_vectors, vec_to_sph

PAPER_RING_SPACING_DEG = 10.0
"""Elevation step between the rings of the paper grid, deg."""

PAPER_AZIMUTH_SPACING_DEG = 10.8
"""Nominal arc spacing (deg on the great circle scale) of the azimuths within a ring."""

KEMAR_ELEVATION_RANGE_DEG = (-40.0, 90.0)
"""Elevation coverage assumed when no HRTF is given (the bundled MIT KEMAR set), deg."""




@dataclass(frozen=True, eq=False)
class DirectionGrid:
    """An ordered set of D directions (immutable).

    Attributes
    ----------
    vectors : numpy.ndarray, shape (D, 3)
        Unit vectors in the head frame (read-only).
    name : str
        Short description, e.g. ``"paper"`` or ``"horizontal_10deg"``.
    azimuth_deg, elevation_deg : numpy.ndarray, shape (D,)
        Azimuth in (-180, 180] (left positive) and elevation in [-90, 90], deg.
    ident : str
        First 16 hex digits of a sha256 over the vectors rounded to 1e-6: equal grids have
        equal idents, on any machine.
    """

    vectors: np.ndarray = field(repr=False)
    name: str = "custom"
    azimuth_deg: np.ndarray = field(init=False, repr=False)
    elevation_deg: np.ndarray = field(init=False, repr=False)
    ident: str = field(init=False)

    def __post_init__(self):
        v = unit_vectors(self.vectors, f"grid {self.name!r} vectors")
        if v.ndim != 2 or v.shape[0] == 0:
            raise ConfigError(f"grid {self.name!r} needs vectors of shape (D >= 1, 3), got {v.shape}")
        az, el = vec_to_sph(v)
        for arr in (v, az, el):
            arr.flags.writeable = False
        # Round before hashing so that -0.0 / 1e-17 noise does not change the ident.
        rounded = np.round(v, 6) + 0.0
        ident = hashlib.sha256(rounded.astype("<f8").tobytes()).hexdigest()[:16]
        object.__setattr__(self, "vectors", v)
        object.__setattr__(self, "azimuth_deg", az)
        object.__setattr__(self, "elevation_deg", el)
        object.__setattr__(self, "ident", ident)
        object.__setattr__(self, "_tree", cKDTree(v))

    def __len__(self) -> int:
        return self.vectors.shape[0]

    def __repr__(self) -> str:
        return f"DirectionGrid(name={self.name!r}, D={len(self)}, ident={self.ident!r})"

    # -- constructors ---------------------------------------------------------------------

    @classmethod
    def from_vectors(cls, vectors, name: str = "custom") -> DirectionGrid:
        """A grid from direction vectors (D, 3) of any non-zero length."""
        return cls(np.asarray(vectors, dtype=float), name=name)

    @classmethod
    def from_angles(cls, azimuth_deg, elevation_deg, name: str = "custom") -> DirectionGrid:
        """A grid from azimuth / elevation arrays in degrees (broadcast against each other)."""
        return cls(np.atleast_2d(sph_to_vec(azimuth_deg, elevation_deg)).reshape(-1, 3), name=name)

    @classmethod
    def paper(cls, hrtf=None, spacing_deg: float = PAPER_RING_SPACING_DEG, *,
              azimuth_spacing_deg: float | None = None, min_elevation_deg: float | None = None,
              max_elevation_deg: float | None = None) -> DirectionGrid:
        """The paper's estimation grid: about 326 directions 10-11 deg apart.

        Elevation rings ``90, 90 - spacing, ...`` inside the coverage, each with
        ``max(1, round(360 cos(el) / azimuth_spacing))`` equally spaced azimuths, every
        other ring rotated by half an azimuth step (see the module docstring for the numbers).

        Parameters
        ----------
        hrtf : HRTF, optional
            Restrict the grid to this set's elevation range (``min_elevation_deg`` /
            ``max_elevation_deg`` attributes); default -40..90 deg (the bundled KEMAR).
        spacing_deg : float
            Elevation step between rings in deg (default 10), in (0, 90].
        azimuth_spacing_deg : float, optional
            Arc spacing of directions within a ring in deg; default
            ``spacing_deg * 1.08`` (10.8 deg for the default, which gives 327 directions
            over -40..90 deg).
        min_elevation_deg, max_elevation_deg : float, optional
            Explicit coverage in deg, overriding ``hrtf``.
        """
        if not (np.isfinite(spacing_deg) and 0 < spacing_deg <= 90):
            raise ConfigError(f"spacing_deg must be in (0, 90], got {spacing_deg}")
        az_step = spacing_deg * PAPER_AZIMUTH_SPACING_DEG / PAPER_RING_SPACING_DEG \
            if azimuth_spacing_deg is None else float(azimuth_spacing_deg)
        if not (np.isfinite(az_step) and 0 < az_step <= 180):
            raise ConfigError(f"azimuth_spacing_deg must be in (0, 180], got {azimuth_spacing_deg}")
        lo, hi = KEMAR_ELEVATION_RANGE_DEG
        if hrtf is not None:
            lo, hi = float(hrtf.min_elevation_deg), float(hrtf.max_elevation_deg)
        lo = lo if min_elevation_deg is None else float(min_elevation_deg)
        hi = hi if max_elevation_deg is None else float(max_elevation_deg)
        if not (-90 <= lo <= hi <= 90):
            raise ConfigError(f"elevation coverage must satisfy -90 <= min <= max <= 90, got {lo}..{hi}")
        els = 90.0 - spacing_deg * np.arange(int(np.floor(180.0 / spacing_deg + 1e-9)) + 1)
        els = els[(els >= lo - 1e-9) & (els <= hi + 1e-9)]
        if els.size == 0:
            raise ConfigError(f"no {spacing_deg} deg elevation ring lies within {lo}..{hi} deg")
        az, el = [], []
        for k, e in enumerate(els):
            n = max(1, round(360.0 * np.cos(np.deg2rad(e)) / az_step))
            offset = 0.5 * (k % 2) * 360.0 / n
            az.append(offset + np.arange(n) * 360.0 / n)
            el.append(np.full(n, e))
        return cls.from_angles(np.concatenate(az), np.concatenate(el), name="paper")

    @classmethod
    def horizontal_plane(cls, step_deg: float = 10.0) -> DirectionGrid:
        """Elevation 0, azimuths 0, step, ..., < 360 deg (front, then counter-clockwise)."""
        if not (np.isfinite(step_deg) and 0 < step_deg <= 180):
            raise ConfigError(f"step_deg must be in (0, 180], got {step_deg}")
        az = np.arange(0.0, 360.0 - 1e-9, step_deg)
        return cls.from_angles(az, np.zeros_like(az), name=f"horizontal_{step_deg:g}deg")

    @classmethod
    def median_plane(cls, step_deg: float = 10.0, min_elevation_deg: float = -40.0,
                     max_elevation_deg: float = 90.0) -> DirectionGrid:
        """Directions in the median plane (y = 0), ordered by the polar angle psi.

        psi runs from ``min_elevation_deg`` in front (azimuth 0) over the top to
        ``180 - min_elevation_deg`` behind (azimuth 180): the direction is
        ``(cos psi, 0, sin psi)``; directions above ``max_elevation_deg`` are left out.
        """
        if not (np.isfinite(step_deg) and 0 < step_deg <= 180):
            raise ConfigError(f"step_deg must be in (0, 180], got {step_deg}")
        if not (-90 <= min_elevation_deg <= max_elevation_deg <= 90):
            raise ConfigError("median plane needs -90 <= min_elevation_deg <= max_elevation_deg <= 90")
        psi = np.arange(min_elevation_deg, 180.0 - min_elevation_deg + 1e-9, step_deg)
        if min_elevation_deg == -90:  # psi = 270 is psi = -90 again
            psi = psi[psi < 270.0 - 1e-9]
        rad = np.deg2rad(psi)
        v = np.stack([np.cos(rad), np.zeros_like(rad), np.sin(rad)], axis=-1)
        v[np.abs(v) < 1e-12] = 0.0
        _, el = vec_to_sph(v)
        v = v[el <= max_elevation_deg + 1e-9]
        if v.shape[0] == 0:
            raise ConfigError("the median-plane range is empty")
        return cls.from_vectors(v, name=f"median_{step_deg:g}deg")

    # -- queries --------------------------------------------------------------------------

    def nearest(self, vectors) -> np.ndarray:
        """Index of the grid direction closest in angle to each vector (..., 3) -> (...)."""
        v = unit_vectors(vectors)
        _, idx = self._tree.query(v.reshape(-1, 3))
        return np.asarray(idx, dtype=np.intp).reshape(v.shape[:-1])

    def nearest_neighbour_angles_deg(self) -> np.ndarray:
        """Angle in deg from each direction to its nearest other direction, shape (D,)."""
        if len(self) < 2:
            raise ConfigError("a grid of one direction has no neighbours")
        _, idx = self._tree.query(self.vectors, k=2)
        return angle_between_deg(self.vectors, self.vectors[idx[:, 1]])


def angular_error_deg(a_vectors, b_vectors) -> np.ndarray:
    """Angle in deg between direction vectors ``a`` and ``b`` (broadcast, (..., 3))."""
    return angle_between_deg(unit_vectors(a_vectors), unit_vectors(b_vectors))


_PLANE_TOLERANCE = 1e-9  # directions this close to a dividing plane lie on it (sin 180 deg != 0)


def is_left(vectors) -> np.ndarray:
    """True where a direction (..., 3) is in the left hemisphere (y > 0).

    Directions on the median plane (|y| <= 1e-9 for unit vectors) are neither left nor
    right: ``is_left`` and ``is_left(-v)`` are both False there. The paper's left/right
    accuracy compares ``is_left`` of the estimate and of the truth.
    """
    return unit_vectors(vectors)[..., 1] > _PLANE_TOLERANCE


def is_front(vectors) -> np.ndarray:
    """True where a direction (..., 3) is in front of the interaural axis (x > 0, same
    tolerance as :func:`is_left`)."""
    return unit_vectors(vectors)[..., 0] > _PLANE_TOLERANCE


def is_up(vectors) -> np.ndarray:
    """True where a direction (..., 3) is above the horizontal plane (z > 0, same tolerance
    as :func:`is_left`)."""
    return unit_vectors(vectors)[..., 2] > _PLANE_TOLERANCE


horizontal_plane = DirectionGrid.horizontal_plane
median_plane = DirectionGrid.median_plane
