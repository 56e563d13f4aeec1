"""The scripted cabin policies: ReverseAlarm and ParkingBrake, from the observation only.

ReverseAlarm
    Push the gearshift along the taught motion (toward D, through R), holding and listening
    at each detent the hand feels, until the reverse alarm is heard *from the front*, then
    let go.
ParkingBrake
    Pull the brake lever along the taught motion until the ratchet is heard *from the right*,
    then let go.

Both follow :class:`~policies.cabin_policy.CabinLeverPolicy` (the vote, listening, waiting for
quiet) and differ in the sound, the accepted region and the motion.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.frames import in_lateral_region, lateral_deg
from policies.cabin_policy import CabinLeverPolicy
from policies.lever_policy import DetentFeel
from policies.task_policy import head_pose
from tasks.base import CONTROL_DT


class ScriptedReverseAlarm(CabinLeverPolicy):
    """Push the gearshift; at each detent the hand feels, hold and listen; let go when the
    reverse alarm is heard from the front.

    Where and when. The car's R and its alarm's relay latency are hidden and vary per
    episode (:data:`tasks.reverse_alarm.HIDDEN_VARIATION`). The hand feels a detent
    (:class:`~policies.lever_policy.DetentFeel`) but not which one, so at each it holds the
    lever and listens for ``listen_s`` of unmasked time (the latency's upper bound and a
    beep); heard from the front, the alarm says this is R and now. Not heard, the push goes
    on. Heard while pushing (a short latency), the lever stops at once, as
    :class:`~policies.cabin_policy.CabinLeverPolicy` does.

    Front and back. Interaural features give a sound's lateral angle (its angle to the
    head's median plane), not where it lies on the cone of confusion: with KEMAR's
    mirror-symmetric ears the dashboard alarm and a beeper behind the car sound the same.
    So the robot listens with its head turned 22 deg to the right (``head_yaw_deg``), which
    puts the dashboard speaker 22 deg left of the head's median plane, and accepts a
    lateral angle of 5-36 deg to the left (``lateral_range_deg``), not above 20 deg up
    (``elevation_deg``).

    Measurements (the poses, regions and waits compared, seed ranges, held-out runs):
    docs/notes/alarm_policy.md.
    """

    side = "left"
    rate_deg_s = 8.0
    max_deg = 30.0
    label = "reverse_alarm"
    window = 8
    votes = 3
    head_yaw_deg = -22.0
    lateral_range_deg = (5.0, 36.0)
    """The lateral angles (deg, + left, from the turned head) accepted as the alarm's: the
    dashboard speaker is 22 deg left of the head turned 22 deg right."""
    elevation_deg = (-90.0, 20.0)
    """The region's elevations (deg, + up, car frame): the dashboard speaker is 10 deg below
    the ears; an estimate more than 30 deg above that is not the alarm."""
    credit_s = 3.0
    """How long after the hand last moved or listened at a detent the alarm can still be its
    doing: the relay's latency (at most 1.5 s) and a beep period (0.8-1.1 s), the first beep
    placed perhaps only in the second one."""
    listen_s = 2.0
    """Unmasked time (s) held at a felt detent before pushing on: the relay's latency (at
    most 1.5 s, :data:`tasks.reverse_alarm.HIDDEN_VARIATION`) and the first beep."""

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.feel = DetentFeel(self.side)
        self.feel.reset(obs)
        self.listened_s: float | None = None  # unmasked time listened at the felt detent; None: pushing

    def should_release(self, obs, info) -> bool:
        if self.feel.push(obs, self.moved):
            self.listened_s = 0.0
        listening = self.listened_s is not None
        if listening:
            self._last_move = self.steps  # what is heard while the hand holds at a detent is its doing
        decided = super().should_release(obs, info)
        if listening:
            if not self.maskers:
                self.listened_s += CONTROL_DT
            if self.listened_s < self.listen_s - 1e-9:
                self.hold, self.waiting = True, "listening"
            else:
                self.listened_s = None  # nothing from the front: not R, or not yet; push on
        return decided

    def accept(self, direction: np.ndarray, obs) -> bool:
        """The alarm's region: the estimate's lateral angle from the turned head (its angle to
        the head's median plane, + left; :func:`lateral_deg`) within ``lateral_range_deg``,
        and its elevation in the car's frame within ``elevation_deg``; ``obs`` gives the
        neck's pitch (:func:`~acoustic_sim.frames.in_lateral_region`)."""
        return in_lateral_region(direction, head_pose(obs)[1], lateral_range_deg=self.lateral_range_deg,
                                 elevation_deg=self.elevation_deg)


class ScriptedParkingBrake(CabinLeverPolicy):
    """Pull the brake lever until the ratchet is heard from the right, then let go.

    "From the right" is a lateral angle (the angle between the direction and the median
    plane, toward the right ear) of at least ``lateral_deg``: the ratchet's pawl is at -108 deg
    azimuth, -63 deg elevation from the head, a lateral angle of 26 deg (the estimates of
    its clicks: 40-55 deg). The lateral angle is what the interaural cues fix; the position
    on the cone of confusion (front, back, up, down) is what they get wrong, so an azimuth
    sector would take a sound's front-back mirror image for the ratchet.

    Measurements (the rule against the azimuth sector, variants not taken, seed ranges,
    held-out runs): docs/notes/parking_brake_policy.md.
    """

    side = "right"
    delay_s = 0.2
    rate_deg_s = 12.0
    """The pull's speed. The brake's teeth are 7 deg apart
    (:data:`acoustic_sim.world.names.BRAKE_TOOTH_ANGLES_DEG`): at 12 deg/s a first click
    that the ears miss or misplace is followed by the next 0.58 s later, after the task's
    0.5 s. Faster pulls were measured and not taken: the arm's motors get louder and mask
    more clicks (:mod:`acoustic_sim.world.egonoise`; docs/notes/parking_brake_policy.md)."""
    max_deg = 45.0
    label = "ratchet"
    head_yaw_deg = 0.0  # the ratchet is far off the median plane: no front-back question
    lateral_deg = 20.0
    window = 6
    votes = 2
    credit_s = 0.064
    """A click is the pawl passing a tooth, which only a moving lever does: one heard more
    than four frames after the pull's command stopped is not the brake's (the ears' decision
    comes one or two frames after the lever stops on a click: it stops when the class is
    heard). The lever itself follows the command up to about 0.2 s late, so a tooth it slides
    over after a stop for another sound goes uncredited; crediting the arm's sensed motion
    instead was measured and not taken (docs/notes/parking_brake_policy.md)."""

    def accept(self, direction: np.ndarray, obs) -> bool:
        return lateral_deg(direction) <= -self.lateral_deg


__all__ = ["ScriptedParkingBrake", "ScriptedReverseAlarm"]
