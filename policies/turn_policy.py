"""The room's gaze: turn the neck, the eyes and the wheelchair toward a direction fixed in the
room (the frame fixed at the episode's start, read from proprioception and odometry).
"""

from __future__ import annotations

import math

import numpy as np

from acoustic_sim.frames import head_to_body_azimuth
from policies.task_policy import TaskPolicy, head_pose


def wrap_rad(angle: float) -> float:
    """An angle (rad) wrapped into [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def fixed_azimuth(obs, v_head, *, mirror: bool = False) -> float:
    """Azimuth (rad, + left) in the frame fixed at the episode's start, from a head-frame vector
    (``mirror``: of its front-back mirror image, see :func:`~acoustic_sim.frames.head_to_body_azimuth`),
    the head turned by :func:`~policies.task_policy.head_pose`."""
    yaw, pitch, heading = head_pose(obs)
    return head_to_body_azimuth(v_head, yaw, pitch, heading=heading, mirror=mirror)


class TurnPolicy(TaskPolicy):
    """Gaze at a direction fixed in the room: neck and eyes, and the wheelchair beyond them.

    ``target`` (rad, fixed frame) is set by subclasses; the gaze moves the neck up to
    ``neck_max_deg`` and the eyes up to ``eye_max_deg``; a target beyond ``turn_body_deg``
    of the wheelchair's heading turns the chair on the spot at ``wheel_speed`` (rad/s)
    until it is within ``stop_body_deg``.
    """

    neck_max_deg = 85.0
    eye_max_deg = 28.0
    turn_body_deg = 140.0
    stop_body_deg = 125.0
    wheel_speed = 4.0

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.target: float | None = None
        self.turning_body = False
        self.turn_sign = 1.0

    def gaze_action(self, obs) -> np.ndarray:
        values = {"left_wheel": 0.0, "right_wheel": 0.0}
        if self.target is not None:
            rel = wrap_rad(self.target - float(obs["base"][0]))
            if abs(rel) > math.radians(self.turn_body_deg):
                if not self.turning_body or abs(rel) < math.radians(150.0):
                    self.turn_sign = 1.0 if rel > 0 else -1.0  # near straight behind: keep turning the same way
                self.turning_body = True
            elif abs(rel) < math.radians(self.stop_body_deg):
                self.turning_body = False
            if self.turning_body:
                w = self.wheel_speed * self.turn_sign
                values.update(left_wheel=-w, right_wheel=w)
            neck = float(np.clip(rel, -math.radians(self.neck_max_deg), math.radians(self.neck_max_deg)))
            eye = float(np.clip(rel - neck, -math.radians(self.eye_max_deg), math.radians(self.eye_max_deg)))
            values.update(neck_yaw=neck, eye_yaw=eye)
        return self.layout.action(values)

    def gaze_settled(self, obs) -> bool:
        """The gaze is at the target and the body still."""
        if self.target is None or self.turning_body:
            return False
        rel = wrap_rad(self.target - float(obs["base"][0]))
        gaze = float(obs["joint_pos"][0]) + float(obs["joint_pos"][2])
        still = abs(float(obs["base"][2])) < 0.05 and float(np.max(np.abs(obs["joint_vel"][:4]))) < 0.1
        return abs(wrap_rad(rel - gaze)) < math.radians(4.0) and still


__all__ = ["TurnPolicy", "fixed_azimuth", "wrap_rad"]
