"""The action vector of the hearing tasks: channel order, ranges, units and the rest pose.

An action is a float32 vector in [-1, 1], one entry per :class:`ActionChannel`: the robot's
joints (:data:`ROBOT_JOINTS`, position servos, rad), then the scene's extra channels: the
two hands' grasp commands in the cabin, the wheelchair's two wheel speeds (rad/s) in the
room. -1 and +1 are the ends of the actuator's control range (:func:`action_layout` reads
them from the model), so the layout converts between physical targets and actions both ways.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scenes
from acoustic_sim.world.view import SceneView

ROBOT_JOINTS: tuple[str, ...] = (*names.NECK_JOINTS, *names.EYE_JOINTS, *names.arm_joints("left"), *names.arm_joints("right"))
"""Joints of the proprioception and of the first action channels, in this order: neck yaw,
pitch; eye yaw, pitch; left arm shoulder pitch, roll, yaw, elbow, wrist; the same for the
right arm."""


@dataclasses.dataclass(frozen=True)
class ActionChannel:
    """One entry of the action vector.

    Attributes
    ----------
    name : str
        Short name (``neck_yaw``, ``left_elbow``, ``grasp_left``, ``left_wheel``).
    target : str
        Full actuator name, or ``grasp:<side>`` for a hand's grasp command.
    low, high : float
        What -1 and +1 mean (rad for joints, rad/s for wheels; grasp: -1 open, +1 hold).
    unit : str
    """

    name: str
    target: str
    low: float
    high: float
    unit: str

    def to_unit(self, value: float) -> float:
        """Physical value -> normalized action in [-1, 1] (clipped)."""
        return float(np.clip(2.0 * (value - self.low) / (self.high - self.low) - 1.0, -1.0, 1.0))

    def from_unit(self, a: float) -> float:
        """Normalized action -> physical value."""
        return self.low + (float(a) + 1.0) * 0.5 * (self.high - self.low)


class ActionLayout:
    """The action vector of a scene: channel order, ranges, and the robot's rest pose.

    Parameters
    ----------
    channels : sequence of ActionChannel
    home : dict of str to float
        Rest value of each channel (rad, rad/s, grasp +-1).
    """

    def __init__(self, channels, home: dict[str, float]) -> None:
        self.channels: tuple[ActionChannel, ...] = tuple(channels)
        self.names: tuple[str, ...] = tuple(c.name for c in self.channels)
        self._index = {c.name: i for i, c in enumerate(self.channels)}
        self.home_values = dict(home)
        self._home = np.array([self._unit(c, home[c.name]) for c in self.channels], dtype=np.float32)

    def __len__(self) -> int:
        return len(self.channels)

    @staticmethod
    def _unit(channel: ActionChannel, value: float) -> float:
        return float(np.clip(value, -1.0, 1.0)) if channel.target.startswith("grasp:") else channel.to_unit(value)

    def index(self, name: str) -> int:
        """Position of channel ``name`` in the action vector."""
        if name not in self._index:
            raise ConfigError(f"no action channel {name!r}; channels: {', '.join(self.names)}")
        return self._index[name]

    def home(self) -> np.ndarray:
        """The normalized action of the rest pose (float32; grasp commands open, wheels still)."""
        return self._home.copy()

    def action(self, values: dict[str, float], base=None) -> np.ndarray:
        """A normalized action (float32) from physical values by channel name (rad, rad/s,
        grasp +-1); channels not given keep ``base`` (default: the rest pose)."""
        a = self.home() if base is None else np.array(base, dtype=np.float32)
        for name, v in values.items():
            i = self.index(name)
            a[i] = self._unit(self.channels[i], v)
        return a

    def arm(self, side: str, angles) -> dict[str, float]:
        """``{channel: angle}`` for the five joints of one arm (rad), shoulder to wrist."""
        return {f"{side}_{s}": float(q) for s, q in zip(names.ARM_JOINT_SUFFIXES, angles)}


def _short(joint: str) -> str:
    return joint[len(names.ROBOT):]


@functools.cache
def action_layout(scene_name: str) -> ActionLayout:
    """The action layout of ``cabin`` (joints + two grasp commands) or ``room`` (joints +
    two wheel speeds); ranges are the actuators' control ranges, the rest pose the robot's
    ``home`` keyframe (read from a freshly loaded scene)."""
    model, data, _ = scenes.load_scene(scene_name)
    view = SceneView(model, data)
    channels, home = [], {}
    for joint in ROBOT_JOINTS:
        act = model.actuator(joint)
        lo, hi = (float(v) for v in act.ctrlrange)
        channels.append(ActionChannel(_short(joint), joint, lo, hi, "rad"))
        home[_short(joint)] = view.control(joint)
    if scene_name == "cabin":
        for side in names.ARM_SIDES:
            channels.append(ActionChannel(f"grasp_{side}", f"grasp:{side}", -1.0, 1.0, "1"))
            home[f"grasp_{side}"] = -1.0
    else:
        for wheel in names.WHEEL_JOINTS:
            act = model.actuator(wheel)
            lo, hi = (float(v) for v in act.ctrlrange)
            short = wheel[len(names.WHEELCHAIR):]
            channels.append(ActionChannel(short, wheel, lo, hi, "rad/s"))
            home[short] = 0.0
    return ActionLayout(channels, home)


__all__ = ["ROBOT_JOINTS", "ActionChannel", "ActionLayout", "action_layout"]
