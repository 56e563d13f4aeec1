"""The cabin's scripted rule: let go when the lever's own sound is heard from where it is made.

Both cabin tasks (ReverseAlarm, ParkingBrake) move a lever that makes the sound the robot
must hear (the alarm on entering R, a click at each of the brake's teeth), so the two
scripted policies share one rule, :class:`CabinLeverPolicy`, and differ in the sound, the
accepted region (:meth:`CabinLeverPolicy.accept`) and the motion
(:mod:`policies.scripted_cabin`).
"""

from __future__ import annotations

import numpy as np

from policies.lever_policy import LeverPolicy
from policies.task_policy import Votes, heard
from tasks.base import CLASSES, CONTROL_DT


class CabinLeverPolicy(LeverPolicy):
    """Move the lever until its ``label`` is heard from the accepted region, then let go.

    Heard from a direction. A frame votes for the target when ``label``'s probability is at
    least ``threshold``, its estimated direction (confidence above ``min_conf``) is in the
    region :meth:`accept` and the lever moved within ``credit_s``; against it when the class
    is heard from elsewhere. The hand lets go when :class:`~policies.task_policy.Votes` of
    ``window`` frames decide (at least ``votes`` for, more for than against). While the
    target is heard and not yet placed elsewhere, the lever stops and the robot listens.

    Waiting for quiet. The lever makes the sound the robot must hear, so the robot also
    chooses *when*. It does not move the lever on while another class is heard (probability
    at least ``masker_level``; not ``own_classes``, the gear lever's own clunks), nor for
    ``masker_quiet_s`` after; nor for ``settle_s`` after its own class was last heard, from
    anywhere (another vehicle's beeper and the turn-signal relay repeat). And a frame votes
    for the target only within ``credit_s`` of the lever's last commanded motion: what is
    heard long after the hand stopped is not the hand's doing. The waits follow only what is
    heard; a cabin that never fell quiet would keep the lever still until the episode's end
    (``timeout``).

    Attributes (class level; ``label``, ``window``, ``votes`` and ``credit_s`` are set by
    each task's policy): ``label`` (the target class), ``threshold`` (class probability),
    ``min_conf`` (direction confidence), ``window`` and ``votes`` (the vote),
    ``credit_s``, ``masker_level``, ``masker_quiet_s``, ``settle_s``, ``own_classes``
    (waiting for quiet). Measurements: docs/notes/alarm_policy.md ("waiting for quiet").
    """

    label: str
    window: int
    votes: int
    credit_s: float
    """How long (s) after the hand stopped the target sound can still be its doing."""
    threshold = 0.5
    min_conf = 0.0
    masker_level = 0.5
    """Probability from which another class counts as masking (the lever waits)."""
    masker_quiet_s = 0.1
    """Quiet time (s) after the last masking frame before the lever moves again."""
    settle_s = 1.5
    """Quiet time (s) after the target class was last heard before the lever moves again: a
    sound of the target's class from elsewhere (another vehicle's beeper, the turn-signal
    relay) repeats, and the next one should not come while the lever makes the real one."""
    own_classes = ("gearshift",)
    """Classes the robot's own hands make (the gear lever's clunks): never a masker."""

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.evidence = Votes(self.window, self.votes)
        self._maskers = [i for i, c in enumerate(CLASSES) if c != self.label and c not in self.own_classes]
        self._last_move = 0
        self._masker_quiet = self._target_quiet = 10**9
        self.waiting: str | None = None  # why the lever stands: "listening", "masked", "settling"
        self.maskers: tuple = ()  # the classes masking in the last frame

    def accept(self, direction: np.ndarray, obs) -> bool:
        """Whether a head-frame direction of the target lies in the accepted region."""
        raise NotImplementedError

    def should_release(self, obs, info) -> bool:
        if not self.hold:  # the lever moved in the last step
            self._last_move = self.steps
        on, d = heard(obs, self.label, self.threshold, self.min_conf)
        accepted = d is not None and self.accept(d, obs)
        credited = self.steps - self._last_move <= round(self.credit_s / CONTROL_DT)
        pro = on and accepted and credited
        con = on and d is not None and not accepted
        decided = self.evidence.push(pro, con)
        # Hearing the sound, stop moving and listen, unless most of the recent frames place
        # it outside the accepted region (another source's: carry on). Moving on while the
        # direction is still being settled would push the lever past the position that
        # made the sound.
        pros = sum(p for p, _ in self.evidence.frames)
        cons = sum(c for _, c in self.evidence.frames)
        self.hold = on and pros >= cons
        # Waiting for quiet: the lever does not move (so makes no sound) while another class
        # masks, nor soon after the target's class was heard from anywhere.
        maskers = tuple(CLASSES[i] for i in self._maskers if float(obs["class_prob"][i]) >= self.masker_level)
        self._masker_quiet = 0 if maskers else self._masker_quiet + 1
        self._target_quiet = 0 if on else self._target_quiet + 1
        self.maskers = maskers
        self.waiting = "listening" if self.hold else None
        if not self.hold and self._masker_quiet < round(self.masker_quiet_s / CONTROL_DT):
            self.hold, self.waiting = True, "masked"
        elif not self.hold and self._target_quiet < round(self.settle_s / CONTROL_DT):
            self.hold, self.waiting = True, "settling"
        return decided


__all__ = ["CabinLeverPolicy"]
