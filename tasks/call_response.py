"""CallResponse: a person calls the robot on its wheelchair; turn until the person is in view."""

from __future__ import annotations

import math
from typing import ClassVar

import mujoco
import numpy as np
from gymnasium import spaces

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scenes
from tasks.base import HearingTaskEnv
from tasks.skills import TurnSkill

ROOM_SIZE = (6.0, 5.0)
"""Floor size (m) of the ``room`` scene (its air volume's x and y)."""

FACING_WEIGHT = 0.3
"""Shaped reward: weight of the facing potential (:meth:`CallResponseEnv._reward_terms`)."""

TIME_WEIGHT = 0.3
"""Shaped reward: what a whole episode's time costs."""

OUT_OF_VIEW_DEG = 50.0
"""The person starts at least this far (deg of bearing) from the robot's line of sight."""


def _yaw(rotation: np.ndarray) -> float:
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class CallResponseEnv(HearingTaskEnv):
    """The paper's call-response task: a person calls the robot from anywhere, behind included;
    the robot turns its head and eyes toward the voice, and its wheelchair when the voice is
    beyond the neck's reach, until the person is in view.

    Description
    -----------
    The robot sits on a wheelchair in a 6 x 5 m room (scene ``room``, RT60 about 0.5 s). A
    person stands 1.4-2.4 m away at a random bearing, facing the robot, and calls ("Musashi,
    over here!": ``human_voice``) soon after the start, and again every 5-7 s while not
    found. A loudspeaker elsewhere in the room plays speech (the same class as the call, from
    another direction) and other sounds at random times: the robot must turn to the *person*.
    The task is solved when the person's head is inside the right eye camera's field of view
    (60 deg vertical, the horizontal angle of ``image_size``) and not occluded (a ray from the
    camera reaches the head first: a geometric check with ``mj_ray``, no rendering).

    {spaces_and_rewards}

    Starting State
    --------------
    The wheelchair at a random point 1.5 m or more from the walls with a random heading, the
    robot in its rest pose (looking straight ahead), after 0.5 s of listening (as in
    ReverseAlarm). The person at a random bearing (uniform, behind included, but at least
    50 deg off the line of sight: out of view) and distance (1.4-2.4 m), facing the robot;
    the loudspeaker at a bearing at least 60 deg away from the person's, 1.3-2.5 m away. The
    first call at 0.3-1.5 s; the loudspeaker plays speech with probability 0.8 (1-2 phrases)
    and another sound (a horn or a key turning) with probability 0.4, at 0.5-25 s, 75 dB SPL
    at 1 m. Background noise 35-45 dB SPL.

    Episode End
    -----------
    Terminated (``success``) when the person is in view. Truncated (``timeout``) after
    ``max_episode_s`` (30 s: the task's limit). ``info``: outcome, ``success``,
    ``person_in_view``, ``person_direction`` (head frame), ``person_bearing_deg`` (relative
    to the wheelchair's heading), ``calls``, ``target_onset_s`` (the first call's start),
    ``found_s``, ``reaction_s`` (first call to in view), the sounds playing with their true
    directions, the events.

    Arguments
    ---------
    ``call_interval_s`` (tuple, default (5.0, 7.0)): seconds from one call's start to the next.
    ``distractors`` (bool, default True): schedule the loudspeaker's sounds.
    {common_arguments}
    """

    task = "call-response"
    scene_name = "room"
    default_max_episode_s = 30.0
    background_db_range = (35.0, 45.0)
    speech_probability = 0.8
    other_probability = 0.4
    WHEEL_RADIUS_M = 0.30
    TRACK_M = 0.60
    spec_action_rows: ClassVar = (
        ("14", "left_wheel (+ forward)", "-5 .. 5", "rad/s"),
        ("15", "right_wheel (+ forward)", "-5 .. 5", "rad/s"),
    )
    spec_action_notes: ClassVar = ("The wheels (0.30 m radius, 0.60 m apart) are velocity servos: equal speeds drive, "
                                   "opposite speeds turn on the spot (right wheel forward turns left, 1 rad/s each way "
                                   "= 57 deg/s).")
    spec_rewards: ClassVar = "+1 when the person comes into view, 0 otherwise."
    spec_shaped_rewards: ClassVar = (
        f"``reward_outcome`` (the sparse reward), ``reward_facing`` (the change of {FACING_WEIGHT:g} x "
        "(1 - the angle between the head's forward and the person / 180 deg): a potential, summing over an "
        f"episode to within +-{FACING_WEIGHT:g}) and ``reward_time`` (-{TIME_WEIGHT:g} / the episode's step limit "
        f"each step). A success returns at least {1 - FACING_WEIGHT - TIME_WEIGHT:g}, a failure at most "
        f"{FACING_WEIGHT:g}.")
    skill_rows: ClassVar = TurnSkill.rows
    spec_observation_rows: ClassVar = (
        ("base", "(3,)", ("the wheelchair's odometry: heading since the start (rad, +-pi, + left), forward speed "
                          "(m/s), yaw rate (rad/s)")),
    )

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, action_mode: str = "joints", reward_mode: str = "sparse",
                 call_interval_s: tuple = (5.0, 7.0), distractors: bool = True,
                 audio_obs: bool = False, spectra_obs: bool = False, image_obs: bool = False,
                 image_size: tuple = (120, 160), torch_threads: int | None = 1) -> None:
        lo, hi = (float(v) for v in call_interval_s)
        if not (np.isfinite(lo) and np.isfinite(hi) and 2.0 <= lo <= hi):
            raise ConfigError(f"call_interval_s must be (low, high) seconds with 2 <= low <= high, got {call_interval_s!r}")
        self.call_interval_s = (lo, hi)
        self.distractors = bool(distractors)
        super().__init__(render_mode=render_mode, profile=profile, hrtf=hrtf, max_episode_s=max_episode_s,
                         action_mode=action_mode, reward_mode=reward_mode,
                         audio_obs=audio_obs, spectra_obs=spectra_obs, image_obs=image_obs, image_size=image_size,
                         torch_threads=torch_threads)
        h, w = self.image_size
        self._tan_v = math.tan(math.radians(60.0) / 2.0)  # the eye cameras' fovy
        self._tan_h = self._tan_v * w / h

    # -- episode ------------------------------------------------------------------------------
    def _scene_config(self, rng: np.random.Generator):
        chair = np.array([rng.uniform(1.5, ROOM_SIZE[0] - 1.5), rng.uniform(1.5, ROOM_SIZE[1] - 1.5)])
        heading = rng.uniform(-180.0, 180.0)
        person, person_bearing = self._place(rng, chair, heading, None)
        speaker, _ = self._place(rng, chair, heading, person_bearing)
        self.person_bearing_deg = float(person_bearing)
        face = math.degrees(math.atan2(chair[1] - person[1], chair[0] - person[0]))
        face_speaker = math.degrees(math.atan2(chair[1] - speaker[1], chair[0] - speaker[0]))
        return scenes.RoomConfig(wheelchair_position=tuple(chair), wheelchair_yaw_deg=float(heading),
                                person_position=tuple(person), person_yaw_deg=face, speaker_position=tuple(speaker),
                                speaker_yaw_deg=face_speaker)

    @staticmethod
    def _place(rng, chair, heading_deg, avoid_bearing):
        """A floor point 0.6 m inside the walls at a random bearing (deg, relative to the
        wheelchair's heading) and distance; at least 60 deg from ``avoid_bearing``."""
        for _ in range(1000):
            bearing = rng.uniform(-180.0, 180.0)
            dist = rng.uniform(1.4, 2.4) if avoid_bearing is None else rng.uniform(1.3, 2.5)
            if avoid_bearing is None and abs(bearing) < OUT_OF_VIEW_DEG:
                continue  # the person starts out of view
            if avoid_bearing is not None and abs(_wrap(math.radians(bearing - avoid_bearing))) < math.radians(60.0):
                continue
            a = math.radians(heading_deg + bearing)
            p = chair + dist * np.array([math.cos(a), math.sin(a)])
            if 0.6 <= p[0] <= ROOM_SIZE[0] - 0.6 and 0.6 <= p[1] <= ROOM_SIZE[1] - 0.6:
                return p, bearing
        raise ConfigError("could not place a person or loudspeaker in the room (this is a bug)")

    def _setup_world(self, model, data, rng) -> None:
        self.found_s: float | None = None
        self.target_onset_s: float | None = None
        self.calls = 0
        self._base_prev: tuple[np.ndarray, float] | None = None
        self._base = np.zeros(3, np.float32)
        self._in_view = False

    def _schedule(self, rng: np.random.Generator) -> None:
        ev = self.coupling.events
        t = rng.uniform(0.3, 1.5)
        self.call_times = []
        while t < self.max_episode_s:
            self.call_times.append(ev.schedule_call(self.at(t)) / ev.sample_rate)
            t += rng.uniform(*self.call_interval_s)
        speech, n_speech = rng.random() < self.speech_probability, int(rng.integers(1, 3))
        speech_times = rng.uniform(0.5, 25.0, size=2)
        other, other_t, other_label = rng.random() < self.other_probability, rng.uniform(0.5, 25.0), rng.choice(["car_horn", "key_turning"])
        if self.distractors:
            plays = [(t, "human_voice") for t in speech_times[: n_speech if speech else 0]]
            if other:
                plays.append((other_t, str(other_label)))
            speaker = self.view.site_position(names.LOUDSPEAKER_SITE)
            for i, (t, label) in enumerate(plays):
                # Drawn from the loudspeaker emitter's own generator: the sounds it would play itself.
                self.schedule_sound(f"loudspeaker{i}", label, ev.draw("loudspeaker", label), speaker, t,
                                    ev.config.loudspeaker_db, frame="world", detail="loudspeaker")
        self.initial_heading = _yaw(self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)[1])
        self._update_base()
        self._in_view, self._image_uv = self.person_in_view()

    # -- vision: the geometric check -------------------------------------------------------------
    def person_in_view(self) -> tuple[bool, tuple[float, float]]:
        """Whether the person's head is in the right eye camera's field of view and not
        occluded, and where (normalized image coordinates u right, v up, each -1..1)."""
        origin, rot = self.view.camera_pose(names.EYE_CAMERAS[1])
        head = self.view.body_pose(names.PERSON_HEAD_BODY)[0]
        d = head - origin
        c = rot.T @ d  # camera frame: x right, y up, looking along -z
        if c[2] >= -1e-6:
            return False, (0.0, 0.0)
        u, v = c[0] / (-c[2]) / self._tan_h, c[1] / (-c[2]) / self._tan_v
        if abs(u) > 1.0 or abs(v) > 1.0:
            return False, (0.0, 0.0)
        return self._unoccluded(origin, head), (float(u), float(v))

    def _unoccluded(self, origin: np.ndarray, target: np.ndarray) -> bool:
        m, d = self.model, self.data
        direction = target - origin
        dist = float(np.linalg.norm(direction))
        direction = direction / dist
        geom = np.zeros(1, np.int32)
        start, travelled = origin.copy(), 0.0
        for _ in range(8):  # skip the robot's own head and eyes around the camera
            hit = mujoco.mj_ray(m, d, start, direction, None, 1, -1, geom)
            if hit < 0 or travelled + hit >= dist + 0.15:
                return False  # nothing on the way: the ray missed the head's geoms
            name = m.body(int(m.geom_bodyid[geom[0]])).name
            if name.startswith(names.PERSON):
                return True
            if not name.startswith(names.ROBOT):
                return False
            travelled += hit + 1e-4
            start = origin + travelled * direction
        return False

    # -- odometry ----------------------------------------------------------------------------------
    def _update_base(self) -> None:
        pos, rot = self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)
        yaw = _yaw(rot)
        if self._base_prev is None:
            speed, rate = 0.0, 0.0
        else:
            p0, y0 = self._base_prev
            dt = 1.0 / self.metadata["render_fps"]
            speed = float(np.dot(pos[:2] - p0[:2], [math.cos(yaw), math.sin(yaw)]) / dt)
            rate = _wrap(yaw - y0) / dt
        self._base_prev = (pos, yaw)
        self._base = np.array([_wrap(yaw - self.initial_heading), np.clip(speed, -5, 5), np.clip(rate, -10, 10)], np.float32)

    def _task_spaces(self) -> dict:
        return {"base": spaces.Box(np.array([-np.pi, -5.0, -10.0], np.float32), np.array([np.pi, 5.0, 10.0], np.float32))}

    def _task_obs(self) -> dict:
        return {"base": np.clip(self._base, [-np.pi, -5.0, -10.0], [np.pi, 5.0, 10.0]).astype(np.float32)}

    # -- actions and rewards ---------------------------------------------------------------------
    def _make_skill(self) -> TurnSkill:
        return TurnSkill(self.layout, self.WHEEL_RADIUS_M, self.TRACK_M)

    def _facing(self) -> float:
        """1 looking straight at the person, 0 with the person straight behind (ground truth)."""
        return 1.0 - math.acos(float(np.clip(self.person_direction()[0], -1.0, 1.0))) / math.pi

    def _shaping_potential(self) -> float:
        return FACING_WEIGHT * self._facing()

    def _reward_terms(self, outcome_reward: float) -> dict[str, float]:
        return {"reward_outcome": float(outcome_reward), "reward_facing": float(self._potential_change()),
                "reward_time": -TIME_WEIGHT / self.max_episode_steps}

    # -- evaluation ---------------------------------------------------------------------------------
    def _evaluate(self):
        self._update_base()
        for e in self.step_events:
            if e["kind"] == "voice_call":
                self.calls += 1
                if self.target_onset_s is None:
                    self.target_onset_s = float(e["time_s"])
        self._in_view, self._image_uv = self.person_in_view()
        if self._in_view and self.outcome == "running":
            self.outcome = "success"
            self.found_s = self.time_s
            return 1.0, True
        return 0.0, self.outcome != "running"

    def person_direction(self) -> np.ndarray:
        """Ground truth: unit vector (head frame) to the person's head."""
        c = self.coupling
        head = c.frame.to_room(self.view.body_pose(names.PERSON_HEAD_BODY)[0])
        v = (head - c.head_position) @ c.head_rotation
        return (v / np.linalg.norm(v)).astype(np.float32)

    def _task_info(self) -> dict:
        pos, rot = self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)
        person = self.view.body_pose(names.PERSON_HEAD_BODY)[0]
        bearing = math.degrees(_wrap(math.atan2(person[1] - pos[1], person[0] - pos[0]) - _yaw(rot)))
        onset = self.target_onset_s
        reaction = None if self.found_s is None or onset is None else self.found_s - onset
        return {
            "success": self.outcome == "success",
            "person_in_view": bool(self._in_view),
            "person_direction": self.person_direction(),
            "person_bearing_deg": float(bearing),
            "calls": int(self.calls),
            "target_onset_s": None if onset is None else float(onset),
            "found_s": None if self.found_s is None else float(self.found_s),
            "reaction_s": None if reaction is None else float(reaction),
            "false_release": False,
        }


__all__ = ["CallResponseEnv"]
