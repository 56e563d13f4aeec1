"""The demo episode step by step: what the robot heard, where it turned, what was really there.

:class:`Trace` is the episode runner's step hook (:func:`apps.runner.run_episode`) that
records, per step, the observation's percept (class probabilities, estimated directions), the
neck's turn, the ground truth of the sounds playing (from ``info``, to tell the reader only),
the ear blocks and the events; :func:`alarm_estimates` reads the reverse alarm's estimates
out of it, as the scripted policy's rule sees them (the narration and the figure share them).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from acoustic_sim.frames import head_to_body_azimuth, head_to_body_elevation, lateral_deg

LABEL = "reverse_alarm"
"""The sound class the demo follows."""


@dataclasses.dataclass
class Trace:
    """What the episode looked like, step by step (the runner's step hook fills it).

    Attributes
    ----------
    t : list of float
        Seconds since the episode's first observation, per step (0 is the reset).
    prob : list of numpy.ndarray
        (6,) class probabilities of the observation.
    direction : list of numpy.ndarray
        (6, 3) estimated direction per class (head frame; zeros: no estimate).
    neck : list of numpy.ndarray
        (2,) the neck's yaw and pitch (rad, proprioception) per step: the head frame's turn
        on the body. Empty (a trace made by hand): the head looks straight ahead.
    confidence : list of numpy.ndarray
        (6,) confidence of each estimate.
    true_az : list of dict
        Per step, the true azimuth (deg, car frame) of each sound playing, by source name
        (ground truth from ``info``, used only to tell the reader what was really there).
    true_lateral : list of dict
        The same for the true lateral angle from the turned head (deg, + left: the angle the
        policy's rule reads; :func:`~acoustic_sim.frames.lateral_deg`).
    labels : dict
        Source name -> sound class of every source that played.
    audio : list of numpy.ndarray
        (2, 705 | 706) digital ear blocks of steps 1, 2, ...
    events : list of tuple
        (seconds since the start, ``info`` event dict).
    start_s : float
        Project-clock time (s) of the episode's first observation (``env.start_s``).
    waiting : list of tuple
        Per step, why the policy's lever stood (``None``, ``"listening"``, ``"masked"`` or
        ``"settling"``, :class:`policies.scripted.ScriptedReverseAlarm`) and the classes that
        masked; empty when the hook that fills it was not given the policy.
    """

    t: list = dataclasses.field(default_factory=list)
    prob: list = dataclasses.field(default_factory=list)
    direction: list = dataclasses.field(default_factory=list)
    neck: list = dataclasses.field(default_factory=list)
    confidence: list = dataclasses.field(default_factory=list)
    true_az: list = dataclasses.field(default_factory=list)
    true_lateral: list = dataclasses.field(default_factory=list)
    labels: dict = dataclasses.field(default_factory=dict)
    audio: list = dataclasses.field(default_factory=list)
    events: list = dataclasses.field(default_factory=list)
    start_s: float = 0.0
    waiting: list = dataclasses.field(default_factory=list)

    def wait_runs(self) -> list[tuple[int, int]]:
        """(first, last) steps of each run in which the lever waited for quiet (``masked`` or
        ``settling``, not ``listening``)."""
        return runs(np.array([w[0] in ("masked", "settling") for w in self.waiting], bool))

    def necks(self) -> list:
        """:attr:`neck` per step, the head straight ahead where the trace has none."""
        return self.neck if self.neck else [np.zeros(2)] * len(self.direction)

    def __call__(self, env, episode, step, obs, reward, terminated, truncated, info) -> None:
        env = env.unwrapped
        if step == 0:
            self.start_s = float(env.start_s)
        self.t.append(float(info["time_s"]) - self.start_s)
        self.prob.append(np.array(obs["class_prob"], dtype=np.float64))
        self.direction.append(np.array(obs["class_dir"], dtype=np.float64).reshape(-1, 3))
        neck = np.array(obs["joint_pos"][:2], dtype=np.float64)
        self.neck.append(neck)
        self.confidence.append(np.array(obs["class_conf"], dtype=np.float64))
        az, lat = {}, {}
        for snd in info["sounding"]:
            az[snd["source"]] = car_azimuth_deg(snd["direction"], neck)
            lat[snd["source"]] = lateral_deg(snd["direction"])
            self.labels[snd["source"]] = snd["label"]
        self.true_az.append(az)
        self.true_lateral.append(lat)
        if step > 0:
            self.audio.append(np.array(env.last_audio, dtype=np.float32))
        for e in info["events"]:
            self.events.append((float(e["time_s"]) - self.start_s, dict(e)))


def azimuth_deg(v) -> float:
    """Azimuth (deg, -180..180, + left) of a vector."""
    return math.degrees(math.atan2(float(v[1]), float(v[0])))


def car_azimuth_deg(v_head, neck=(0.0, 0.0), *, mirror: bool = False) -> float:
    """Azimuth (deg, + left) in the car's frame of a head-frame vector, the neck turned by
    ``neck`` = (yaw, pitch) rad; ``mirror``: of its front-back mirror image through the
    head's interaural axis (what the ears cannot tell it from)."""
    return math.degrees(head_to_body_azimuth(v_head, float(neck[0]), float(neck[1]), mirror=mirror))


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True in a boolean array."""
    idx = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return [(int(a), int(b) - 1) for a, b in zip(idx[::2], idx[1::2])]


def alarm_estimates(trace: Trace) -> tuple[np.ndarray, ...]:
    """Per step: the reverse alarm's probability, its estimated direction (head frame),
    whether it has one, and that estimate's lateral angle from the head and elevation in the
    car's frame (deg; NaN without an estimate)."""
    from acoustic_sim.acoustics.sounds import SOUND_CLASSES

    k = SOUND_CLASSES.index(LABEL)
    p = np.array([x[k] for x in trace.prob])
    d = np.array([x[k] for x in trace.direction])
    has = np.linalg.norm(d, axis=1) > 0.5
    lat = np.array([lateral_deg(v) if h else np.nan for v, h in zip(d, has)])
    el = np.array([math.degrees(head_to_body_elevation(v, float(n[1]))) if h else np.nan
                   for v, n, h in zip(d, trace.necks(), has)])
    return p, d, has, lat, el


__all__ = ["LABEL", "Trace", "alarm_estimates", "azimuth_deg", "car_azimuth_deg", "runs"]
