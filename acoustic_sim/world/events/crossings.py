"""The mechanisms' detectors: lever detents and ratchet teeth from traces of hinge angles.

Mechanisms are observed at every 2 ms physics step. A crossing (into a detent's capture
zone, of the ratchet pawl snapping back) is placed by linear interpolation between the two
physics steps around it, as a fractional position in the trace; the event source
(:class:`~acoustic_sim.world.events.SoundEvents`) turns that position into a sample of the
project clock.
"""

from __future__ import annotations

import math

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world.lever_geometry import GearshiftGeometry, RatchetGeometry


def _crossing(a: float, b: float, level: float) -> float:
    """Fraction (0, 1] of the segment a -> b at which it reaches ``level``."""
    return (level - a) / (b - a)


class GearshiftTracker:
    """Which detent the lever is in, with hysteresis, from a trace of hinge angles.

    Parameters
    ----------
    geometry : GearshiftGeometry
    angle : float
        The initial hinge angle (rad); the lever starts in the detent whose capture zone
        holds it, or in none.
    """

    def __init__(self, geometry: GearshiftGeometry, angle: float) -> None:
        self.geometry = geometry
        # Plain floats: the tracker runs every control step, on 8 samples.
        d, c, r = (np.asarray(v, dtype=float) for v in (geometry.detents_rad, geometry.capture_rad, geometry.release_rad))
        self._capture_lo, self._capture_hi = (d - c).tolist(), (d + c).tolist()
        self._release_lo, self._release_hi = (d - r).tolist(), (d + r).tolist()
        self.reset(angle)

    def reset(self, angle: float) -> None:
        """Restart at ``angle`` (rad) without events."""
        g = self.geometry.position(angle)
        self.gear: int | None = None if g is None else self.geometry.names.index(g)
        self.last_gear: int | None = self.gear
        self.angle = float(angle)

    def update(self, angles) -> list[tuple[float, str, int]]:
        """Advance over new angle samples; returns ``(position, "enter" | "leave", gear)``.

        ``position`` is the trace position of the crossing: ``j + u`` for a crossing at
        fraction ``u`` (0..1] of the segment from sample ``j - 1`` to ``j`` (sample -1 is
        the last angle of the previous call). Crossings are in time order.
        """
        trace = [float(v) for v in angles]
        if not trace:
            return []
        if not all(map(math.isfinite, trace)):
            raise ConfigError("gearshift angle trace is not finite (did the simulation diverge?)")
        lo, hi = min(self.angle, *trace), max(self.angle, *trace)
        # Fast path (nearly every step): the trace stays in the current detent's release zone,
        # or, between detents, touches no capture zone.
        if self.gear is not None:
            if self._release_lo[self.gear] <= lo and hi <= self._release_hi[self.gear]:
                self.angle = trace[-1]
                return []
        elif not any(c0 <= hi and c1 >= lo for c0, c1 in zip(self._capture_lo, self._capture_hi)):
            self.angle = trace[-1]
            return []
        out: list[tuple[float, str, int]] = []
        a = self.angle
        for j, b in enumerate(trace):
            u0 = 0.0  # the segment a -> b, from fraction u0 on
            while True:
                start = a + u0 * (b - a)
                if self.gear is not None:
                    r0, r1 = self._release_lo[self.gear], self._release_hi[self.gear]
                    if r0 <= b <= r1:
                        break
                    u = _crossing(a, b, r1 if b > r1 else r0)
                    out.append((j + u, "leave", self.gear))
                    self.gear, u0 = None, u
                    continue
                # Not in a detent: the first capture edge reached in the direction of motion.
                if b == start:
                    break
                if b > start:
                    hits = [g for g, e in enumerate(self._capture_lo) if start < e <= b]
                    g = hits[0] if hits else None
                    edge = self._capture_lo[g] if hits else 0.0
                else:
                    hits = [g for g, e in enumerate(self._capture_hi) if b <= e < start]
                    g = hits[-1] if hits else None
                    edge = self._capture_hi[g] if hits else 0.0
                if g is None:
                    break
                u = max(_crossing(a, b, edge), u0)
                out.append((j + u, "enter", g))
                self.gear, u0 = g, u
            a = b
        self.angle = a
        return out


class RatchetTracker:
    """Ratchet clicks from traces of the brake lever's and the pawl's angles.

    A click is the pawl snapping back after a pin has lifted it: the pawl angle falls
    through ``pawl_drop_rad`` after having risen above ``pawl_lift_rad``. It counts when
    the lever has reached a tooth that has not clicked yet (so a pawl bouncing on its stop
    does not click twice); a tooth clicks again once the lever has gone back below it
    (which takes the release button). Pulling with the button held passes teeth silently;
    letting the button go then drops the pawl behind the highest one: one click.

    Parameters
    ----------
    geometry : RatchetGeometry
    lever : float
        The initial lever angle (rad); teeth already passed do not click.
    pawl : float
        The initial pawl angle (rad).
    """

    def __init__(self, geometry: RatchetGeometry, lever: float, pawl: float) -> None:
        self.geometry = geometry
        self.reset(lever, pawl)

    def reset(self, lever: float, pawl: float) -> None:
        """Restart at these angles (rad) without events."""
        self.clicked = self.geometry.teeth_engaged(lever)  # teeth 1..clicked have clicked
        self.lifted = pawl > self.geometry.pawl_lift_rad
        self.pawl = float(pawl)

    def update(self, levers, pawls) -> list[tuple[float, int]]:
        """Advance over new angle samples (rad); returns ``(position, tooth)`` per click.

        ``position`` as in :meth:`GearshiftTracker.update`; teeth are 1-based.
        """
        g = self.geometry
        out: list[tuple[float, int]] = []
        levers = [float(v) for v in levers]
        pawls = [float(v) for v in pawls]
        if len(levers) != len(pawls):
            raise ConfigError(f"ratchet traces differ in length: {len(levers)} lever and {len(pawls)} pawl angles")
        if not levers:
            return out
        if not (all(map(math.isfinite, levers)) and all(map(math.isfinite, pawls))):
            raise ConfigError("brake or pawl angle trace is not finite (did the simulation diverge?)")
        lever_min, pawl_max = min(levers), max(pawls)
        if not self.lifted and pawl_max <= g.pawl_lift_rad:
            # Fast path: the pawl stays down, so nothing clicks; teeth the lever went below re-arm.
            self.clicked = min(self.clicked, g.teeth_engaged(lever_min))
            self.pawl = pawls[-1]
            return out
        a = self.pawl
        for j, (lever, b) in enumerate(zip(levers, pawls)):
            engaged = g.teeth_engaged(lever)
            self.clicked = min(self.clicked, engaged)
            if b > g.pawl_lift_rad:
                self.lifted = True
            elif self.lifted and b < g.pawl_drop_rad:
                self.lifted = False
                if engaged > self.clicked:
                    self.clicked = engaged
                    out.append((j + _crossing(a, b, g.pawl_drop_rad) if a > g.pawl_drop_rad else j + 1.0, engaged))
            a = b
        self.pawl = a
        return out
