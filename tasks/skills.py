"""The ``skill`` action mode: a small action space for learners, in which exploring is safe.

The ``joints`` mode's 16 channels are the robot's servos and grasp commands: a random action
opens the hand half the time, so a cabin episode explored at random ends within two steps.
A skill maps a small normalized Box onto a joints-mode action each step, holding the rest of
the robot in its rest pose:

- :class:`LeverSkill` (cabin): the lever's speed along its taught motion
  (:func:`tasks.levers.lever_arm_angles`) and a release that must be commanded deliberately
  (above :data:`RELEASE_LEVEL` for :data:`RELEASE_STEPS` steps in a row).
- :class:`TurnSkill` (room): the neck's yaw rate and the wheelchair's turn rate on the spot.

In both, the zero action keeps everything as it is: nothing moves and nothing lets go.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
from gymnasium import spaces

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE
from tasks.actions import ActionLayout
from tasks.levers import lever_arm_angles, lever_motion

ACTION_MODES = ("joints", "skill")
"""The tasks' ``action_mode`` values."""

DT = 1.0 / FRAME_RATE

RELEASE_LEVEL = 0.8
"""The release component must exceed this ..."""

RELEASE_STEPS = 3
"""... for this many consecutive steps (48 ms) to let go. A learner's usual first policy, a
unit Gaussian around 0, holds on for about 100 steps (1.6 s) per release (0.21 ** 3 per
step); uniform noise for about 1000 (16 s); a decision costs 32 ms more than one step."""


class Skill:
    """Maps a skill action (normalized Box) to a joints-mode action; keeps its own state."""

    rows: ClassVar[tuple[tuple[str, str, str, str], ...]] = ()
    """The docstring's action table rows: (idx, component, range, meaning)."""

    def __init__(self, layout: ActionLayout) -> None:
        self.layout = layout
        self.space = spaces.Box(-1.0, 1.0, shape=(len(self.rows),), dtype=np.float32)

    def reset(self, env) -> None:
        """Start of an episode (after the world is set up)."""

    def to_joints(self, a: np.ndarray) -> np.ndarray:
        """The joints-mode action (float32) of skill action ``a`` (clipped to [-1, 1])."""
        raise NotImplementedError


class LeverSkill(Skill):
    """Cabin: move the held lever along its taught motion; let go deliberately.

    The commanded lever angle starts at 0 (the lever's rest) and moves at the commanded speed,
    within the taught motion's reach; the arm follows the taught joint angles at that angle.
    The other arm, the neck and the eyes hold the rest pose.
    """

    max_rate_deg_s = 20.0
    """Lever speed (deg/s) of a component of +-1 (the scripted policies push at 8-16)."""
    rows: ClassVar = (
        ("0", "lever_rate", "-1 .. 1", f"lever speed along the taught motion, x {max_rate_deg_s:g} deg/s (+ away from rest)"),
        ("1", "release", "-1 .. 1", f"> {RELEASE_LEVEL:g} for {RELEASE_STEPS} steps in a row opens the hand; else it holds"),
    )

    def __init__(self, layout: ActionLayout, side: str) -> None:
        super().__init__(layout)
        self.side = side
        self.max_deg = float(lever_motion(side)[0][-1])

    def reset(self, env) -> None:
        self.lever_deg = 0.0
        self.pressed = 0
        self.released = False

    def to_joints(self, a: np.ndarray) -> np.ndarray:
        rate, release = (float(v) for v in np.clip(a, -1.0, 1.0))
        self.pressed = self.pressed + 1 if release > RELEASE_LEVEL else 0
        self.released = self.released or self.pressed >= RELEASE_STEPS
        if not self.released:
            self.lever_deg = float(np.clip(self.lever_deg + rate * self.max_rate_deg_s * DT, 0.0, self.max_deg))
        values = self.layout.arm(self.side, lever_arm_angles(self.side, self.lever_deg))
        values[f"grasp_{self.side}"] = -1.0 if self.released else 1.0
        return self.layout.action(values)


class TurnSkill(Skill):
    """Room: turn the head (neck yaw) and the wheelchair on the spot.

    The neck's commanded yaw moves at the commanded rate within its range; the wheels turn in
    opposite directions at the speed that gives the commanded turn rate. The eyes and the
    arms hold the rest pose.
    """

    max_neck_deg_s = 90.0
    """Neck yaw rate (deg/s) of a component of +-1."""
    max_turn_deg_s = 90.0
    """Wheelchair turn rate (deg/s, on the spot) of a component of +-1."""
    rows: ClassVar = (
        ("0", "neck_yaw_rate", "-1 .. 1", f"neck yaw rate, x {max_neck_deg_s:g} deg/s (+ left), within its range"),
        ("1", "turn_rate", "-1 .. 1", f"wheelchair turn rate on the spot, x {max_turn_deg_s:g} deg/s (+ left)"),
    )

    def __init__(self, layout: ActionLayout, wheel_radius_m: float, track_m: float) -> None:
        super().__init__(layout)
        ch = layout.channels[layout.index("neck_yaw")]
        self.neck_range = (ch.low, ch.high)
        self.wheel_per_turn = track_m / (2.0 * wheel_radius_m)  # wheel rad/s per chassis rad/s
        wheel = layout.channels[layout.index("right_wheel")]
        if math.radians(self.max_turn_deg_s) * self.wheel_per_turn > wheel.high + 1e-9:
            raise ConfigError(f"turn rate {self.max_turn_deg_s} deg/s needs more than the wheels' {wheel.high} rad/s")

    def reset(self, env) -> None:
        self.neck_yaw = float(self.layout.home_values["neck_yaw"])

    def to_joints(self, a: np.ndarray) -> np.ndarray:
        neck, turn = (float(v) for v in np.clip(a, -1.0, 1.0))
        self.neck_yaw = float(np.clip(self.neck_yaw + neck * math.radians(self.max_neck_deg_s) * DT, *self.neck_range))
        wheel = turn * math.radians(self.max_turn_deg_s) * self.wheel_per_turn
        return self.layout.action({"neck_yaw": self.neck_yaw, "left_wheel": -wheel, "right_wheel": wheel})


__all__ = ["ACTION_MODES", "RELEASE_LEVEL", "RELEASE_STEPS", "LeverSkill", "Skill", "TurnSkill"]
