"""The scripted room policy: CallResponse, from the observation only.

When a voice is heard, turn the head and eyes toward it, and the wheelchair when it is
beyond the neck's reach (:class:`~policies.turn_policy.TurnPolicy`), until the person is in
view. A direction that turned out to hold no person (the loudspeaker, a front-back
confusion) is remembered and not checked again; a voice from there is tried at its
front-back mirror image instead.
"""

from __future__ import annotations

import math

import numpy as np

from policies.task_policy import heard
from policies.turn_policy import TurnPolicy, fixed_azimuth, wrap_rad
from tasks.base import CLASSES, CONTROL_DT


class ScriptedCallResponse(TurnPolicy):
    """Turn toward the voice; if nobody is there, remember the direction and wait for the next
    call (a voice from a remembered direction is tried at its front-back mirror image).

    A direction is decided from ``decide_frames`` frames in which the voice was heard with
    a direction (or fewer, at least ``min_frames``, when the voice stops for ``gap_frames``):
    the confidence-weighted circular mean of their azimuths in the fixed frame.
    """

    threshold = 0.5
    min_conf = 0.0
    decide_frames = 8
    min_frames = 3
    gap_frames = 10
    look_s = 0.4
    same_deg = 30.0

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.frames: list[tuple[float, float, float]] = []  # (azimuth, mirrored azimuth, weight)
        self.gap = 0
        self.checked: list[float] = []
        self.settled_steps = 0

    def _mean(self, k: int) -> float:
        w = np.array([f[2] for f in self.frames])
        a = np.array([f[k] for f in self.frames])
        return math.atan2(float(np.sum(w * np.sin(a))), float(np.sum(w * np.cos(a))))

    def _is_checked(self, az: float) -> bool:
        return any(abs(wrap_rad(az - c)) < math.radians(self.same_deg) for c in self.checked)

    def _decide(self) -> None:
        direct, mirror = self._mean(0), self._mean(1)
        self.frames.clear()
        for candidate in (direct, mirror):
            if not self._is_checked(candidate):
                if self.target is None or abs(wrap_rad(candidate - self.target)) > math.radians(self.same_deg):
                    self.target = candidate
                    self.settled_steps = 0
                return

    def act(self, obs, info) -> np.ndarray:
        on, d = heard(obs, "human_voice", self.threshold, self.min_conf)
        if on and d is not None:
            w = 0.1 + float(obs["class_conf"][CLASSES.index("human_voice")])
            self.frames.append((fixed_azimuth(obs, d), fixed_azimuth(obs, d, mirror=True), w))
            self.gap = 0
        else:
            self.gap += 1
        if len(self.frames) >= self.decide_frames or (self.gap >= self.gap_frames and len(self.frames) >= self.min_frames):
            self._decide()
        elif self.gap >= self.gap_frames:
            self.frames.clear()
        if self.gaze_settled(obs):
            self.settled_steps += 1
            if self.settled_steps * CONTROL_DT >= self.look_s:  # looked, nobody there
                self.checked.append(self.target)
                if len(self.checked) > 4:
                    self.checked = self.checked[-2:]
                self.settled_steps = -10**9  # until a new target
        action = self.gaze_action(obs)
        self.steps += 1
        return action


__all__ = ["ScriptedCallResponse"]
