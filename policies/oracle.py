"""The oracle: the scripted behaviours driven by the ground truth in ``info``.

It acts on the step after the target sound starts (the alarm, the required tooth's click,
the person's call), from its true direction: the upper bound of the behaviour, what perfect
hearing would give.
"""

from __future__ import annotations

import numpy as np

from policies.lever_policy import LeverPolicy
from policies.scripted_cabin import ScriptedParkingBrake, ScriptedReverseAlarm
from policies.turn_policy import TurnPolicy, fixed_azimuth


class OracleLeverPolicy(LeverPolicy):
    """Move the lever; let go on the first step after the target sound has started (``info``)."""

    def should_release(self, obs, info) -> bool:
        return info.get("target_onset_s") is not None


class OracleReverseAlarm(OracleLeverPolicy):
    """Push the gearshift until the lever is at this car's R (``info["hidden"]``), hold it
    there, let go on the first step after the alarm has started (``info``)."""

    side = "left"
    rate_deg_s = ScriptedReverseAlarm.rate_deg_s  # the same taught push as the scripted policy's
    max_deg = ScriptedReverseAlarm.max_deg
    stop_before_deg = 0.3
    """How far (deg) before R's valley the push stops: the lever lags the command by about
    0.1 deg and the detent's spring pulls it the rest of the way."""

    def should_release(self, obs, info) -> bool:
        r = info.get("hidden", {}).get("reverse_deg", 15.0)
        self.hold = self.hold or (info.get("gear") == "R" and info.get("gear_deg", 0.0) >= r - self.stop_before_deg)
        return super().should_release(obs, info)


POLICY_CLASSES = {"reverse-alarm": OracleReverseAlarm}
"""Task name -> oracle policy class."""


class OracleParkingBrake(OracleLeverPolicy):
    """Pull the brake; let go on the first step after the required tooth has clicked (``info``)."""

    side = "right"
    rate_deg_s = ScriptedParkingBrake.rate_deg_s  # the same taught pull as the scripted policy's
    max_deg = ScriptedParkingBrake.max_deg


POLICY_CLASSES["parking-brake"] = OracleParkingBrake


class OracleCallResponse(TurnPolicy):
    """Turn toward the person's true direction as soon as the person's call has started."""

    def act(self, obs, info) -> np.ndarray:
        for s in info.get("sounding", []):
            if s["source"] == "voice":
                self.target = fixed_azimuth(obs, s["direction"])
        action = self.gaze_action(obs)
        self.steps += 1
        return action


POLICY_CLASSES["call-response"] = OracleCallResponse
