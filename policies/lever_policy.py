"""The cabin's hand on a lever: the taught motion, held or resumed, and letting go.

A :class:`LeverPolicy` moves its lever along the taught motion until
:meth:`LeverPolicy.should_release` says so, then opens the hand; subclasses decide when (the
scripted ones from what is heard, :mod:`policies.cabin_policy`; the oracle from ``info``).
"""

from __future__ import annotations

import math

import numpy as np

from acoustic_sim.world import names
from policies.task_policy import TaskPolicy
from tasks.actions import ROBOT_JOINTS
from tasks.base import CONTROL_DT, lever_arm_angles


class DetentFeel:
    """Feel a lever's detents through the arm holding it (proprioception, no hearing).

    Where the lever's roller drops into a detent's valley, the detent's spring pulls the lever
    and the hand with it: an arm joint's velocity changes by 0.008-0.033 rad/s in one step
    (R anywhere in 7-23 deg, pushed at 8 deg/s), against under 0.003 along a steady push. The
    arm's own starts and stops change it as much for about 0.1 s, so a change counts only
    after ``steady_s`` of uninterrupted commanded motion
    (:attr:`LeverPolicy.moved`). Leaving P is felt too when R is far
    from it (R above 20 deg): a feel says *a* detent, not which.

    Parameters
    ----------
    side : str
        The arm on the lever (``"left"`` or ``"right"``).
    threshold_rad_s : float
        The velocity change (rad/s) between two steps that counts as a detent.
    steady_s : float
        Uninterrupted motion (s) before a change counts.
    refractory_s : float
        Time (s) after a feel before the next can count (one detent, one feel).
    """

    def __init__(self, side: str, *, threshold_rad_s: float = 0.006, steady_s: float = 0.2,
                 refractory_s: float = 0.3) -> None:
        self.joints = [i for i, j in enumerate(ROBOT_JOINTS) if j in names.arm_joints(side)]
        self.threshold_rad_s, self.steady_s, self.refractory_s = float(threshold_rad_s), float(steady_s), float(refractory_s)

    def reset(self, obs) -> None:
        self._last = np.asarray(obs["joint_vel"][self.joints], dtype=float)
        self._moving_s = 0.0
        self._since_feel_s = float("inf")
        self.felt = 0  # detents felt this episode

    def push(self, obs, moving: bool) -> bool:
        """One step's observation, and whether the lever was commanded to move in it; True
        when a detent is felt in this step."""
        vel = np.asarray(obs["joint_vel"][self.joints], dtype=float)
        jump = float(np.max(np.abs(vel - self._last)))
        self._last = vel
        self._moving_s = self._moving_s + CONTROL_DT if moving else 0.0
        self._since_feel_s += CONTROL_DT
        if self._moving_s >= self.steady_s - 1e-9 and jump >= self.threshold_rad_s and self._since_feel_s >= self.refractory_s:
            self._since_feel_s = 0.0
            self.felt += 1
            return True
        return False


class LeverPolicy(TaskPolicy):
    """Move a lever along the taught motion until :meth:`should_release`, then open the hand.

    Attributes (class level)
    ------------------------
    side : str
        The hand on the lever.
    delay_s, rate_deg_s, max_deg : float
        The taught motion: still for ``delay_s``, then ``rate_deg_s`` up to ``max_deg``.
    head_yaw_deg : float
        The neck's yaw (deg, + left) held during the episode: the listening pose.
    """

    side = "left"
    delay_s = 0.2
    rate_deg_s = 8.0
    max_deg = 30.0
    head_yaw_deg = 0.0

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.released = False
        self.hold = False
        self.motion_s = 0.0
        self.moved = False  # whether the last action moved the lever's command
        self._arm = lever_arm_angles(self.side, 0.0)

    def lever_target_deg(self) -> float:
        return float(np.clip(self.rate_deg_s * (self.motion_s - self.delay_s), 0.0, self.max_deg))

    def should_release(self, obs, info) -> bool:
        """Decide from this observation; may set ``self.hold`` to pause the motion."""
        raise NotImplementedError

    def act(self, obs, info) -> np.ndarray:
        if not self.released and self.should_release(obs, info):
            self.released = True
        before = self.lever_target_deg()
        if not self.released:
            if not self.hold:
                self.motion_s += CONTROL_DT
            self._arm = lever_arm_angles(self.side, self.lever_target_deg())
        self.moved = not self.released and self.lever_target_deg() != before
        values = self.layout.arm(self.side, self._arm)
        values["neck_yaw"] = math.radians(self.head_yaw_deg)
        values[f"grasp_{self.side}"] = -1.0 if self.released else 1.0
        self.steps += 1
        return self.layout.action(values)


__all__ = ["DetentFeel", "LeverPolicy"]
