"""The scripted cabin policies: ReverseAlarm and ParkingBrake, from the observation only.

ReverseAlarm
    Push the gearshift along the taught motion (toward D, through R) until the reverse alarm
    is heard *from the front*, then let go.
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
from policies.task_policy import head_pose


class ScriptedReverseAlarm(CabinLeverPolicy):
    """Push the gearshift until the reverse alarm is heard from the front, then let go.

    Parameters (class level): ``head_yaw_deg`` (the neck's yaw while listening, deg, + left),
    ``lateral_range_deg`` (the lateral angles from the turned head accepted as the alarm's,
    deg, + left), ``elevation_deg`` (their elevations in the car's frame, deg); the rest as
    for :class:`~policies.cabin_policy.CabinLeverPolicy`.

    Front and back. Interaural features give a sound's lateral angle (its angle to the
    head's median plane), not where it lies on the cone of confusion: with KEMAR's
    mirror-symmetric ears the dashboard alarm and a beeper behind the car sound the same.
    So the robot listens with its head turned 22 deg to the right (``head_yaw_deg``), which
    puts the dashboard speaker 22 deg left of the head's median plane, and accepts a
    lateral angle of 5-36 deg to the left (``lateral_range_deg``), not above 20 deg up
    (``elevation_deg``): the front of the car and its mirror image behind on the left. A
    beeper straight behind the car is then at lateral -22 deg, those beside it on the left
    at 70-90 deg.

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
    the ears; an estimate more than 30 deg above that is not the alarm; below, no bound (its
    beeps are placed down to -50 deg; measurements: docs/notes/alarm_policy.md)."""
    credit_s = 1.0
    """How long after the hand stopped the alarm can still be its doing: the alarm sounds as
    long as the lever stays in R, one beep every 0.8-1.1 s, so a beep in the second after the
    hand stopped may be the first one the ears place."""

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
