"""Taught lever motions of the cabin tasks: how each arm moves its lever, and the start pose.

The robot knows its own arm and the cabin's layout, as the paper's robot was taught its
motions: for every angle of a lever along its arc (the gearshift for the left hand, the
parking brake for the right), the arm joint angles that keep the palm on the handle
(:func:`lever_motion`, by inverse kinematics once per process). A policy moves a lever by
commanding :func:`lever_arm_angles`; :func:`hold_lever` puts the hand on its lever at the
start of an episode (through :mod:`acoustic_sim.world.actuation`, whose :func:`settle` is
re-exported here).
"""

from __future__ import annotations

import functools
import math

import mujoco
import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import actuation, names, scenes
from acoustic_sim.world.actuation import settle
from acoustic_sim.world.view import WorldView

LEVERS = {"left": (names.GEARSHIFT_JOINT, names.GEARSHIFT_KNOB_SITE), "right": (names.BRAKE_JOINT, names.BRAKE_HANDLE_SITE)}
"""Each hand's lever in the cabin: (hinge joint, handle site)."""


@functools.cache
def lever_motion(side: str, step_deg: float = 0.5, max_deg: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    """A taught motion: arm joint angles that move a hand's lever along its arc.

    The robot's knowledge of its own arm and of the cabin's layout (as the paper's robot was
    taught its motions): for lever angles 0, ``step_deg``, ... ``max_deg`` (deg from the rest
    angle of the scene's initial state, the gearshift in P and the brake down), the angles of
    the five arm joints that put the palm where it holds the handle, by position inverse
    kinematics (:func:`acoustic_sim.world.actuation.reach`) on a freshly loaded cabin, each
    solution warm-started from the previous one. Angles the arm cannot reach end the table.

    Returns
    -------
    lever_deg : numpy.ndarray, shape (K,)
    arm : numpy.ndarray, shape (K, 5)
        rad, shoulder pitch, roll, yaw, elbow, wrist.
    """
    if side not in LEVERS:
        raise ConfigError(f"side must be 'left' (gearshift) or 'right' (brake), got {side!r}")
    model, data, _ = scenes.load_scene("cabin")
    joint, site = LEVERS[side]
    view = WorldView(model, data)
    anchor, axis = view.joint_axis(joint)
    handle = view.site_position(site)
    angles, rows = [], []
    for deg in np.arange(0.0, max_deg + 1e-9, step_deg):
        r = _rotation(axis, np.deg2rad(deg))
        target = anchor + r @ (handle - anchor)
        try:
            q = actuation.reach(model, data, side, target, max_error=0.01)
        except ConfigError:
            break
        for arm_joint, angle in zip(names.arm_joints(side), q):  # warm start for the next angle
            actuation.set_joint_position(model, data, arm_joint, angle)
        angles.append(deg)
        rows.append(q)
    return np.asarray(angles), np.asarray(rows)


def lever_arm_angles(side: str, lever_deg: float) -> np.ndarray:
    """Arm joint angles (rad, (5,)) of the taught motion at lever angle ``lever_deg``
    (interpolated, clamped to the reachable part of the arc)."""
    deg, arm = lever_motion(side)
    return np.array([np.interp(lever_deg, deg, arm[:, j]) for j in range(arm.shape[1])])


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def hold_lever(model: mujoco.MjModel, data: mujoco.MjData, side: str) -> None:
    """Start state of a cabin task: the hand on its lever (the taught pose at the lever's
    rest angle), settled, and closed on the handle."""
    arm = lever_arm_angles(side, 0.0)
    for joint, q in zip(names.arm_joints(side), arm):
        actuation.set_joint_position(model, data, joint, q)
        actuation.set_control(model, data, joint, q)
    actuation.forward(model, data)
    settle(model, data, 0.2)
    if not actuation.grasp(model, data, side):
        raise ConfigError(f"the {side} hand could not close on its lever at the start of the episode")
    settle(model, data, 0.1)


__all__ = ["LEVERS", "hold_lever", "lever_arm_angles", "lever_motion", "settle"]
