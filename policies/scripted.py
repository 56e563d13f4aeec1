"""The paper's behaviours, from the observation only (never ``info``): the ``scripted`` policies.

ReverseAlarm, ParkingBrake
    Move the lever along the taught motion until its sound is heard from where the lever
    makes it (the alarm *from the front*, the ratchet *from the right*), then let go; wait for
    quiet before moving it on (:mod:`policies.cabin_policy`, :mod:`policies.scripted_cabin`).
CallResponse
    Turn toward a heard voice until the person is in view, remembering directions that held
    nobody (:mod:`policies.scripted_room`).
"""

from __future__ import annotations

from policies.scripted_cabin import ScriptedParkingBrake, ScriptedReverseAlarm
from policies.scripted_room import ScriptedCallResponse

POLICY_CLASSES = {
    "reverse-alarm": ScriptedReverseAlarm,
    "parking-brake": ScriptedParkingBrake,
    "call-response": ScriptedCallResponse,
}
"""Task name -> scripted policy class."""

__all__ = ["POLICY_CLASSES", "ScriptedCallResponse", "ScriptedParkingBrake", "ScriptedReverseAlarm"]
