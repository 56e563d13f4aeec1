"""The scripted room policy: CallResponse, from the observation only.

When a voice is heard, turn the gaze toward it (:class:`~policies.turn_policy.TurnPolicy`),
and keep listening while turning: every frame votes for its direction *and* its front-back
mirror image in the room's fixed frame. A turning head moves the mirror image and leaves the
true direction put, so the votes pile up on the caller and the gaze follows the peak. A
direction looked at with nobody there is struck out. Measurements: docs/notes/call_response.md.
"""

from __future__ import annotations

import math

import numpy as np

from policies.task_policy import heard
from policies.turn_policy import TurnPolicy, fixed_azimuth, wrap_rad
from tasks.base import CLASSES, CONTROL_DT

BINS = 72
"""Azimuth bins of the vote map (5 deg each)."""

_CENTRES = np.arange(BINS) * (2.0 * math.pi / BINS) - math.pi


class ScriptedCallResponse(TurnPolicy):
    """Turn to the peak of a vote map over room azimuths, fed by the voice's frames.

    Each frame in which the voice is heard with a direction adds a von Mises bump (width
    ``kappa``) at its azimuth in the fixed frame, weight ``direct_weight``, and one at its
    front-back mirror image, weight 1 - ``direct_weight`` (the ears' front-back cues are
    weak). After ``min_frames`` frames the gaze goes to the map's peak, or between it and a
    runner-up within ``switch_margin`` of it and ``pair_deg`` of it (a front-back pair: both
    are in view from the side between them), and follows that point when it moves by
    ``move_deg``. Looked at for ``look_s`` with the episode still running: nobody there; the
    direction is struck out. The start's field of view (``seen_deg`` either side) is struck
    out at once: the task places every person out of view (what the eyes would tell a robot
    that used them).
    """

    threshold = 0.5
    min_conf = 0.0
    min_frames = 3
    kappa = 12.0
    direct_weight = 0.5
    switch_margin = 1.5
    same_deg = 30.0
    pair_deg = 85.0
    move_deg = 12.0
    look_s = 0.35
    seen_deg = 45.0

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.votes = np.zeros(BINS)
        self.frames = 0
        self.struck = (np.abs(_CENTRES) > math.radians(self.seen_deg)).astype(float)
        self.settled_steps = 0

    def _vote(self, azimuth: float, weight: float) -> None:
        self.votes += weight * np.exp(self.kappa * (np.cos(_CENTRES - azimuth) - 1.0))

    def _peak(self) -> float:
        return float(_CENTRES[int(np.argmax(self.votes * self.struck))])

    def _strike(self, azimuth: float) -> None:
        self.struck *= 1.0 - np.exp(self.kappa * (np.cos(_CENTRES - azimuth) - 1.0))

    def _desired(self) -> float:
        """The map's peak; between it and the runner-up when that one is nearly as strong and
        near enough that both are in view from between (a front-back pair about the side)."""
        scores = self.votes * self.struck
        first = int(np.argmax(scores))
        away = np.abs(np.angle(np.exp(1j * (_CENTRES - _CENTRES[first])))) > math.radians(self.same_deg)
        second = int(np.argmax(np.where(away, scores, -1.0)))
        a, b = float(_CENTRES[first]), float(_CENTRES[second])
        if scores[second] * self.switch_margin >= scores[first] and abs(wrap_rad(b - a)) <= math.radians(self.pair_deg):
            return wrap_rad(a + wrap_rad(b - a) / 2.0)
        return a

    def act(self, obs, info) -> np.ndarray:
        on, d = heard(obs, "human_voice", self.threshold, self.min_conf)
        if on and d is not None:
            w = 0.1 + float(obs["class_conf"][CLASSES.index("human_voice")])
            self._vote(fixed_azimuth(obs, d), w * self.direct_weight)
            self._vote(fixed_azimuth(obs, d, mirror=True), w * (1.0 - self.direct_weight))
            self.frames += 1
        if self.frames >= self.min_frames:
            self._aim(self._desired())
        return self._look_and_act(obs)

    def _aim(self, desired: float) -> None:
        """Gaze at ``desired`` (rad, fixed frame) unless the gaze is within ``move_deg`` of it."""
        if self.target is None or abs(wrap_rad(desired - self.target)) >= math.radians(self.move_deg):
            self.target, self.settled_steps = desired, 0

    def _after_strike(self) -> float | None:
        """Where to look once the target has been struck out: the vote map's next peak."""
        return self._peak() if float((self.votes * self.struck).max()) > 0 else None

    def _look_and_act(self, obs) -> np.ndarray:
        """Strike out a direction looked at for ``look_s`` with nobody there; the gaze's action."""
        if self.gaze_settled(obs):
            self.settled_steps += 1
            if self.settled_steps * CONTROL_DT >= self.look_s:  # looked: nobody there
                self._strike(self.target)
                self.target, self.settled_steps = self._after_strike(), 0
        action = self.gaze_action(obs)
        self.steps += 1
        return action


class TrackedCallResponse(ScriptedCallResponse):
    """Turn toward the pipeline's world-frame track of the voice (``tracked_dir``) instead of
    the policy's own vote map: a variant, measured against it in docs/notes/active_hearing.md
    (0.60 against 0.70 on the design seeds, with the room's evidence rule set to
    ``wavefront+coherence``; with the task's ``wavefront`` the voice gives the tracker too few
    frames).

    Until the tracker has decided front from back (``tracked_decided``), the gaze goes between
    the track and its mirror image (the side they share, as the vote map's pair rule does), and
    the turn toward that side is what lets the tracker decide. A direction looked at with
    nobody there is struck out as in the parent; a struck-out track gives way to its mirror.
    """

    def act(self, obs, info) -> np.ndarray:
        i = CLASSES.index("human_voice")
        if float(obs["tracked_conf"][i]) > 0.0:
            d = np.asarray(obs["tracked_dir"][3 * i : 3 * i + 3], float)
            az, mirror = fixed_azimuth(obs, d), fixed_azimuth(obs, d, mirror=True)
            k = int(np.argmin(np.abs(np.angle(np.exp(1j * (_CENTRES - az))))))
            if self.struck[k] < 0.5:
                az = mirror
            self._aim(az if obs["tracked_decided"][i] > 0.5 else wrap_rad(az + wrap_rad(mirror - az) / 2.0))
        return self._look_and_act(obs)

    def _after_strike(self) -> float | None:
        return None  # the next frame's track sets the target


__all__ = ["ScriptedCallResponse", "TrackedCallResponse"]
