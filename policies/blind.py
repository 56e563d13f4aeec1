"""The blind policy: hears the classes but ignores their directions.

It lets go on any reverse alarm (ReverseAlarm) or any ratchet-like click (ParkingBrake),
with the same evidence rule as ``scripted`` (``votes`` of the last ``window`` frames) but
without the direction test, so the distractors bite: its false releases measure what
hearing the direction is worth.

The scripted cabin policies also wait for quiet before moving the lever
(:class:`policies.cabin_policy.CabinLeverPolicy`), which needs no direction. The blind
policies stay as the issue defines them (any alarm or click, no waiting); what the waiting
is worth without the direction test (it does not stand in for the direction):
docs/notes/blind_policy.md.
"""

from __future__ import annotations

import numpy as np

from policies.scripted_cabin import ScriptedParkingBrake, ScriptedReverseAlarm
from policies.task_policy import heard
from policies.deaf import DeafCallResponse


class BlindReverseAlarm(ScriptedReverseAlarm):
    """Push the gearshift; let go when a reverse alarm is heard, wherever it is."""

    head_yaw_deg = 0.0  # no direction test, so no listening pose

    def should_release(self, obs, info) -> bool:
        on, _ = heard(obs, self.label, self.threshold, self.min_conf)
        return self.evidence.push(on, False)


POLICY_CLASSES = {"reverse-alarm": BlindReverseAlarm}
"""Task name -> blind policy class."""


class BlindParkingBrake(ScriptedParkingBrake):
    """Pull the brake; let go when a ratchet-like click is heard, wherever it is."""

    def should_release(self, obs, info) -> bool:
        on, _ = heard(obs, self.label, self.threshold, self.min_conf)
        return self.evidence.push(on, False)


POLICY_CLASSES["parking-brake"] = BlindParkingBrake


class BlindCallResponse(DeafCallResponse):
    """On hearing a voice, scan the room as the deaf policy does (its search's winner) from
    that moment on: it knows when someone called, not where."""

    threshold = 0.5

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.first_heard: float | None = None

    def scan_start_s(self, obs) -> float | None:
        if self.first_heard is None and heard(obs, "human_voice", self.threshold, 0.0)[0]:
            self.first_heard = self.time_s
        return self.first_heard


POLICY_CLASSES["call-response"] = BlindCallResponse
