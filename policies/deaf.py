"""The deaf baseline: the best open-loop behaviour that never reads the percept.

A task is worth having only if hearing decides it; the deaf policy bounds what a behaviour
can do without ears. It reads no percept (no ``class_*``, ``audio`` or ``spectra``), only
its own clock, its arm's joints and, in the room, the proprioception and odometry that steer
the gaze.

ReverseAlarm
    Push the gearshift along the taught motion at ``rate_deg_s`` until the hand feels a
    detent (its own arm's joint velocities: proprioception, not hearing), hold ``wait_s``,
    let go.
ParkingBrake
    Move the lever along the taught motion at ``rate_deg_s`` to ``target_deg``, hold it
    there ``wait_s``, then let go.
CallResponse
    Scan the room at ``turn_deg_s`` (``direction`` +1 left, -1 right), in jumps of
    ``step_deg`` with a stop to look after each (or a sweep), the neck first and the
    wheelchair beyond it, until the episode ends.

The class defaults are what :mod:`apps.deaf_search` found best on design seeds
(``acoustic-sim deaf-search TASK`` reruns the search; every point's score is in
``results/deaf_search/``, what they show in docs/notes/deaf_baseline.md); ``eval tasks``
measures them on held-out seeds like every other policy.
"""

from __future__ import annotations

import math

import numpy as np

from policies.lever_policy import DetentFeel, LeverPolicy
from policies.turn_policy import TurnPolicy


class DeafLeverPolicy(LeverPolicy):
    """Move the lever to ``target_deg`` at ``rate_deg_s``, hold ``wait_s``, let go.

    Parameters
    ----------
    env : gymnasium.Env
        The task env.
    target_deg : float, optional
        Lever angle (deg, within the taught motion's range) to move to; default the class's.
    rate_deg_s : float, optional
        Speed (deg/s, > 0) along the taught motion; default the class's.
    wait_s : float, optional
        Time (s, >= 0) to hold at ``target_deg`` before letting go; default the class's.
    """

    target_deg = 12.0
    wait_s = 0.0

    def __init__(self, env, *, target_deg: float | None = None, rate_deg_s: float | None = None,
                 wait_s: float | None = None) -> None:
        super().__init__(env)
        self.target_deg = float(self.target_deg if target_deg is None else target_deg)
        self.rate_deg_s = float(self.rate_deg_s if rate_deg_s is None else rate_deg_s)
        self.wait_s = float(self.wait_s if wait_s is None else wait_s)
        if not (self.rate_deg_s > 0 and self.wait_s >= 0 and self.target_deg >= 0):
            raise ValueError(f"deaf lever policy needs target_deg >= 0, rate_deg_s > 0, wait_s >= 0, got "
                             f"{self.target_deg}, {self.rate_deg_s}, {self.wait_s}")
        self.max_deg = self.target_deg

    def release_time_s(self) -> float:
        """When the hand opens (s from the episode's start): the taught motion's delay, the
        travel to ``target_deg``, the wait."""
        return self.delay_s + self.target_deg / self.rate_deg_s + self.wait_s

    def should_release(self, obs, info) -> bool:
        return self.time_s >= self.release_time_s() - 1e-9


class DeafReverseAlarm(LeverPolicy):
    """Push the gearshift until the hand feels a detent, hold it ``wait_s``, let go.

    The car's R moves per episode (:data:`tasks.reverse_alarm.HIDDEN_VARIATION`), so no fixed
    lever angle finds it; the hand does (:class:`~policies.lever_policy.DetentFeel`: R's
    valley is felt in every car, and leaving P too when R is above 20 deg). What it cannot
    feel is when the alarm's relay starts the alarm: ``wait_s`` is the best guess.

    Parameters
    ----------
    env : gymnasium.Env
        The task env.
    rate_deg_s : float, optional
        Speed (deg/s, > 0) along the taught motion; default the class's.
    wait_s : float, optional
        Time (s, >= 0) from feeling the detent to letting go; default the class's.
    """

    side = "left"
    rate_deg_s = 16.0
    max_deg = 30.0
    wait_s = 0.4

    def __init__(self, env, *, rate_deg_s: float | None = None, wait_s: float | None = None) -> None:
        super().__init__(env)
        self.rate_deg_s = float(self.rate_deg_s if rate_deg_s is None else rate_deg_s)
        self.wait_s = float(self.wait_s if wait_s is None else wait_s)
        if not (self.rate_deg_s > 0 and self.wait_s >= 0):
            raise ValueError(f"deaf ReverseAlarm policy needs rate_deg_s > 0, wait_s >= 0, got {self.rate_deg_s}, "
                             f"{self.wait_s}")
        self.feel = DetentFeel(self.side)

    def reset(self, obs, info, seed: int | None = None) -> None:
        super().reset(obs, info, seed)
        self.feel.reset(obs)
        self.felt_s: float | None = None

    def should_release(self, obs, info) -> bool:
        if self.feel.push(obs, self.moved) and self.felt_s is None:
            self.felt_s = self.time_s
        self.hold = self.felt_s is not None
        return self.hold and self.time_s - self.felt_s >= self.wait_s - 1e-9


class DeafParkingBrake(DeafLeverPolicy):
    """Pull the parking brake to a fixed angle, hold, let go (never listening)."""

    side = "right"
    rate_deg_s = 16.0
    target_deg = 13.0
    wait_s = 0.0


class DeafCallResponse(TurnPolicy):
    """Scan the room at a fixed average rate and direction, never listening: in jumps of
    ``step_deg`` (a stop after each, to look), or a continuous sweep (``step_deg`` 0; below
    30 deg/s the gaze counts as still, so a slow sweep looks as it goes).

    Parameters
    ----------
    env : gymnasium.Env
        The task env.
    turn_deg_s : float, optional
        Average rate of the gaze's target (deg/s, > 0); default the class's.
    direction : int, optional
        +1 to scan left (counter-clockwise from above), -1 right; default the class's.
    step_deg : float, optional
        The jump (deg, >= 0; 0: a sweep); default the class's.
    """

    turn_deg_s = 60.0
    direction = -1
    step_deg = 45.0

    def __init__(self, env, *, turn_deg_s: float | None = None, direction: int | None = None,
                 step_deg: float | None = None) -> None:
        super().__init__(env)
        self.turn_deg_s = float(self.turn_deg_s if turn_deg_s is None else turn_deg_s)
        self.direction = int(self.direction if direction is None else direction)
        self.step_deg = float(self.step_deg if step_deg is None else step_deg)
        if not (self.turn_deg_s > 0 and self.direction in (-1, 1) and self.step_deg >= 0):
            raise ValueError(f"deaf call-response policy needs turn_deg_s > 0, direction +-1 and step_deg >= 0, got "
                             f"{self.turn_deg_s}, {self.direction}, {self.step_deg}")

    def scan_start_s(self, obs) -> float | None:
        """When the scan starts (s of the episode; None: not yet): at once."""
        return 0.0

    def act(self, obs, info) -> np.ndarray:
        start = self.scan_start_s(obs)
        if start is None:
            self.steps += 1
            return self.gaze_action(obs)
        sweep = self.turn_deg_s * (self.time_s - start)
        if self.step_deg > 0:
            sweep = self.step_deg * (1.0 + math.floor(sweep / self.step_deg))  # the first jump at once
        self.target = self.direction * math.radians(sweep)
        action = self.gaze_action(obs)
        self.steps += 1
        return action


POLICY_CLASSES = {
    "reverse-alarm": DeafReverseAlarm,
    "parking-brake": DeafParkingBrake,
    "call-response": DeafCallResponse,
}
"""Task name -> deaf policy class."""

SEARCH_PARAMETERS = {
    "reverse-alarm": ("rate_deg_s", "wait_s"),
    "parking-brake": ("target_deg", "rate_deg_s", "wait_s"),
    "call-response": ("turn_deg_s", "step_deg", "direction"),
}
"""The open-loop parameters :mod:`apps.deaf_search` chooses, per task."""

__all__ = ["POLICY_CLASSES", "SEARCH_PARAMETERS", "DeafCallResponse", "DeafLeverPolicy", "DeafParkingBrake",
           "DeafReverseAlarm"]
