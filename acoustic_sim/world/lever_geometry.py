"""The cabin levers' geometry: the gearshift's detents and the parking brake's ratchet teeth.

The mechanisms' geometry is part of the assets: the cabin model carries it as MuJoCo custom
numerics (:data:`names.GEAR_DETENTS_NUMERIC`, :data:`names.BRAKE_TEETH_NUMERIC`), which
:class:`~acoustic_sim.world.view.WorldView` reads into :class:`GearshiftGeometry` and
:class:`RatchetGeometry`. Both are pure functions of joint angles: the event trackers use them
on angle traces, without MuJoCo.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names


@dataclasses.dataclass(frozen=True, kw_only=True)
class GearshiftGeometry:
    """Detent positions of the gearshift hinge.

    Parameters
    ----------
    detents_rad : tuple of float
        Joint angle (rad) of each detent, strictly increasing, in the order of ``names``.
    names : tuple of str
        Gear names, default P, R, N, D.
    capture_fraction : float
        The lever is *in* a detent when it is closer to it than this fraction of the
        distance to the nearest neighbouring detent; 0 < capture < release.
    release_fraction : float
        Once in a detent, the lever stays in it until it is farther than this fraction
        (hysteresis, so a lever resting at the capture edge does not chatter); < 0.5, so
        the release zones of neighbours never overlap.
    """

    detents_rad: tuple[float, ...]
    names: tuple[str, ...] = names.GEAR_NAMES
    capture_fraction: float = 0.3
    release_fraction: float = 0.45

    def __post_init__(self) -> None:
        d = np.asarray(self.detents_rad, dtype=float)
        if d.ndim != 1 or d.size < 2 or d.size != len(self.names) or not np.all(np.isfinite(d)) or np.any(np.diff(d) <= 0):
            raise ConfigError(
                f"gearshift detents must be {len(self.names)} strictly increasing finite angles (rad) for gears "
                f"{self.names}, got {self.detents_rad}"
            )
        if not 0.0 < self.capture_fraction < self.release_fraction < 0.5:
            raise ConfigError(
                f"gearshift capture/release fractions must satisfy 0 < capture < release < 0.5, got "
                f"{self.capture_fraction} and {self.release_fraction}"
            )

    @property
    def spacing(self) -> np.ndarray:
        """Distance (rad) from each detent to its nearest neighbour, shape (G,)."""
        gaps = np.diff(np.asarray(self.detents_rad, dtype=float))
        return np.minimum(np.r_[gaps[0], gaps], np.r_[gaps, gaps[-1]])

    @property
    def capture_rad(self) -> np.ndarray:
        """Capture half-width (rad) of each detent, shape (G,)."""
        return self.capture_fraction * self.spacing

    @property
    def release_rad(self) -> np.ndarray:
        """Release half-width (rad) of each detent, shape (G,)."""
        return self.release_fraction * self.spacing

    def position(self, angle: float) -> str | None:
        """The gear whose capture zone holds ``angle`` (rad), or ``None`` between detents."""
        d = np.asarray(self.detents_rad)
        i = int(np.argmin(np.abs(d - angle)))
        return self.names[i] if abs(d[i] - angle) < self.capture_rad[i] else None

    def angle(self, name: str) -> float:
        """Detent angle (rad) of gear ``name``."""
        if name not in self.names:
            raise ConfigError(f"unknown gear {name!r}; gears: {self.names}")
        return float(self.detents_rad[self.names.index(name)])


@dataclasses.dataclass(frozen=True, kw_only=True)
class RatchetGeometry:
    """The parking brake's ratchet: pins on the lever's sector pass under a sprung pawl.

    Pulling the lever up, each pin lifts the pawl and passes; the pawl snaps back behind
    it (the click) and then holds the lever on that pin when the hand lets go.

    Parameters
    ----------
    teeth_rad : tuple of float
        Lever angle (rad) at which it rests on tooth ``k`` (held by the pawl), k = 1..n,
        strictly increasing.
    rest_tolerance_fraction : float
        A lever this fraction of the smallest tooth pitch below a tooth's rest angle still
        rests on it (contacts are soft), 0-0.5.
    pawl_lift_rad : float
        The pawl counts as lifted by a passing pin above this angle (rad).
    pawl_drop_rad : float
        A lifted pawl falling below this angle (rad) has snapped back: a click;
        0 <= drop < lift.
    """

    teeth_rad: tuple[float, ...]
    rest_tolerance_fraction: float = 0.25
    pawl_lift_rad: float = float(np.deg2rad(4.0))
    pawl_drop_rad: float = float(np.deg2rad(1.5))

    def __post_init__(self) -> None:
        t = np.asarray(self.teeth_rad, dtype=float)
        if t.ndim != 1 or t.size < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ConfigError(f"ratchet teeth must be one or more strictly increasing finite angles (rad), got {self.teeth_rad}")
        if not 0.0 <= self.rest_tolerance_fraction <= 0.5:
            raise ConfigError(f"ratchet: rest_tolerance_fraction must be 0..0.5, got {self.rest_tolerance_fraction}")
        if not 0.0 <= self.pawl_drop_rad < self.pawl_lift_rad:
            raise ConfigError(
                f"ratchet: pawl thresholds must satisfy 0 <= drop < lift (rad), got {self.pawl_drop_rad}, {self.pawl_lift_rad}"
            )

    @property
    def n_teeth(self) -> int:
        """Number of teeth."""
        return len(self.teeth_rad)

    @functools.cached_property
    def tolerance_rad(self) -> float:
        """How far (rad) below a tooth's rest angle the lever still rests on it."""
        t = np.asarray(self.teeth_rad, dtype=float)
        pitch = float(np.min(np.diff(t))) if t.size > 1 else float(np.deg2rad(5.0))
        return self.rest_tolerance_fraction * pitch

    @functools.cached_property
    def _thresholds(self) -> list[float]:
        return [float(t) - self.tolerance_rad for t in self.teeth_rad]

    def teeth_engaged(self, angle: float) -> int:
        """Number of teeth (0..n) the lever at ``angle`` (rad) is at or above: the tooth the
        pawl holds it on (0: fully down)."""
        return bisect.bisect_right(self._thresholds, angle)


__all__ = ["GearshiftGeometry", "RatchetGeometry"]
