"""The cabin's hand on a lever: the taught motion, held or resumed, and letting go.

A :class:`LeverPolicy` moves its lever along the taught motion until
:meth:`LeverPolicy.should_release` says so, then opens the hand; subclasses decide when (the
scripted ones from what is heard, :mod:`policies.cabin_policy`; the oracle from ``info``).
"""

from __future__ import annotations

import math

import numpy as np

from policies.task_policy import TaskPolicy
from tasks.base import CONTROL_DT, lever_arm_angles


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
        self._arm = lever_arm_angles(self.side, 0.0)

    def lever_target_deg(self) -> float:
        return float(np.clip(self.rate_deg_s * (self.motion_s - self.delay_s), 0.0, self.max_deg))

    def should_release(self, obs, info) -> bool:
        """Decide from this observation; may set ``self.hold`` to pause the motion."""
        raise NotImplementedError

    def act(self, obs, info) -> np.ndarray:
        if not self.released and self.should_release(obs, info):
            self.released = True
        if not self.released:
            if not self.hold:
                self.motion_s += CONTROL_DT
            self._arm = lever_arm_angles(self.side, self.lever_target_deg())
        values = self.layout.arm(self.side, self._arm)
        values["neck_yaw"] = math.radians(self.head_yaw_deg)
        values[f"grasp_{self.side}"] = -1.0 if self.released else 1.0
        self.steps += 1
        return self.layout.action(values)


__all__ = ["LeverPolicy"]
