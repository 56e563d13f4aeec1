"""CallResponse: a person calls the robot on its wheelchair; turn until the person is in view."""

from __future__ import annotations

import math
from typing import ClassVar

import mujoco
import numpy as np
from gymnasium import spaces

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scenes
from tasks.base import CONTROL_DT, HearingTaskEnv
from tasks.skills import TurnSkill

ROOM_SIZE = (6.0, 5.0)
"""Floor size (m) of the ``room`` scene (its air volume's x and y)."""

FACING_WEIGHT = 0.3
"""Shaped reward: weight of the facing potential (:meth:`CallResponseEnv._reward_terms`)."""

TIME_WEIGHT = 0.3
"""Shaped reward: what a whole episode's time costs."""

OUT_OF_VIEW_DEG = 50.0
"""Every person starts at least this far (deg of bearing) from the robot's line of sight."""

APART_DEG = 60.0
"""The people stand at least this far apart (deg of bearing from the wheelchair)."""

LOOK_S = 0.25
"""A look: a person in view while the gaze is still (below :data:`STILL_DEG_S`), this long (s).
A turn sweeping past someone is not a look (a saccade does not fixate)."""

STILL_DEG_S = 30.0
"""The gaze is still below this angular speed (deg/s, the right eye camera's forward axis in
the world)."""

RESPONSE_WINDOW_S = 1.5
"""The default response window (s from the first call's start to the end of the look), from
the neck's and wheelchair's speeds (``scripts/turn_speeds.py``; docs/notes/call_response.md):
with perfect hearing 0.3 s after the call starts, a turn the right way ends its look within
1.28 s for every caller (the neck and eyes reach 113 deg in 0.2 s; a caller behind needs the
wheelchair), a turn the wrong way not before 1.36 s, and mostly near 1.7 s (the wheelchair
turns the long way round). Within 1.5 s the wrong way succeeds only for callers near straight
behind, where both ways are right."""

CROWD = {"people": (3, 3), "response_window_s": RESPONSE_WINDOW_S, "look_s": LOOK_S}
"""The defaults: three people, one of whom calls; the first person turned to and looked at
after the call decides (the caller: ``success``; another: ``wrong_person``), within the window.
With two people a deaf scan picks the caller in half the episodes (0.50 on 20 design seeds,
docs/notes/call_response.md); ``people=(2, 3)`` draws either."""

PAPER_ROOM = {"people": (1, 1), "response_window_s": None, "look_s": 0.0}
"""Arguments for the paper's room: one person, found when in view, within the episode's limit
(the setting before the crowd; a deaf sweep finds the person every time)."""


def _yaw(rotation: np.ndarray) -> float:
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class CallResponseEnv(HearingTaskEnv):
    """The paper's call-response task in a crowd: one of two or three people calls the robot
    from anywhere, behind included; the robot turns its head and eyes toward the voice, and
    its wheelchair when the voice is beyond the neck's reach, and looks at the caller.

    Description
    -----------
    The robot sits on a wheelchair in a 6 x 5 m room (scene ``room``, RT60 about 0.5 s).
    Three people (``people``: two or three, or one) stand 1.4-2.4 m away at random bearings,
    facing the robot; one of them (the *person*, the caller) calls ("Musashi, over here!": ``human_voice``) soon after the
    start, and again every 5-7 s; the others are silent. A loudspeaker elsewhere in the room
    plays speech (the same class as the call, from another direction) and other sounds at
    random times. Only the voice tells which person called: the robot must look at the
    caller, not at whoever it meets first, and soon. A person is in view when the head is
    inside the right eye camera's field of view (60 deg vertical, the horizontal angle of
    ``image_size``) and not occluded (a ray from the camera reaches that head first: a
    geometric check with ``mj_ray``, no rendering); looked at when in view with the gaze still
    (below 30 deg/s, :data:`STILL_DEG_S`) for ``look_s``.

    {spaces_and_rewards}

    Starting State
    --------------
    The wheelchair at a random point 1.5 m or more from the walls with a random heading, the
    robot in its rest pose (looking straight ahead), after 0.5 s of listening (as in
    ReverseAlarm). Each person at a random bearing (uniform, behind included, but at least
    50 deg off the line of sight: out of view, and 60 deg from each other) and distance
    (1.4-2.4 m), facing the robot; which one calls is drawn too;
    the loudspeaker at a bearing at least 60 deg away from the person's, 1.3-2.5 m away. The
    first call at 0.3-1.5 s; the loudspeaker plays speech with probability 0.8 (1-2 phrases)
    and another sound (a horn or a key turning) with probability 0.4, at 0.5-25 s, 75 dB SPL
    at 1 m. Background noise 35-45 dB SPL.

    Episode End
    -----------
    Terminated by the first person looked at after the first call starts (in view, the gaze
    still for ``look_s``): ``success`` for the caller (who wins when several are in view),
    ``wrong_person`` for another; ``too_late`` when ``response_window_s`` passes first (from
    the call's start). Looks before the call do not count, nor does a person already in view
    when it starts until the gaze has left them: the robot must turn to the caller. Truncated
    (``timeout``) after ``max_episode_s`` (30 s: the task's limit). ``info``: outcome, ``success``, ``people``,
    ``looked_at`` (``caller``, a bystander's name or None), ``bystander_bearings_deg``,
    ``person_in_view``, ``person_direction`` (head frame), ``person_bearing_deg`` (relative
    to the wheelchair's heading), ``calls``, ``target_onset_s`` (the first call's start),
    ``found_s``, ``reaction_s`` (first call to the look's end), the sounds playing with their true
    directions, the events.

    Arguments
    ---------
    ``people`` (tuple, default (3, 3)): the range of the number of people (1-3), drawn per
    episode; one of them calls, the others stay silent.
    ``response_window_s`` (float or None, default 1.5): the caller must be looked at within
    this many seconds of the first call's start (``too_late`` otherwise; why 1.5 s:
    :data:`RESPONSE_WINDOW_S`); None: until the episode's limit.
    ``look_s`` (float, default 0.25): how long a person must be in view with the gaze still
    (:data:`LOOK_S`) to count as looked at; 0: in view at any speed counts (the paper's check).
    :data:`PAPER_ROOM` holds the paper's setting (one person, no window, in view).
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
    spec_rewards: ClassVar = "+1 when the caller is looked at, 0 otherwise (``wrong_person``, ``too_late``, ``timeout``)."
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
                 people: tuple = CROWD["people"], response_window_s: float | None = RESPONSE_WINDOW_S,
                 look_s: float = LOOK_S, call_interval_s: tuple = (5.0, 7.0), distractors: bool = True,
                 audio_obs: bool = False, spectra_obs: bool = False, image_obs: bool = False,
                 image_size: tuple = (120, 160), torch_threads: int | None = 1) -> None:
        lo, hi = (float(v) for v in call_interval_s)
        if not (np.isfinite(lo) and np.isfinite(hi) and 2.0 <= lo <= hi):
            raise ConfigError(f"call_interval_s must be (low, high) seconds with 2 <= low <= high, got {call_interval_s!r}")
        self.call_interval_s = (lo, hi)
        try:
            n_lo, n_hi = (int(v) for v in people)
        except (TypeError, ValueError):
            n_lo = n_hi = -1
        if not (1 <= n_lo <= n_hi <= 1 + len(names.BYSTANDERS)) or tuple(people) != (n_lo, n_hi):
            raise ConfigError(f"people must be (low, high) integers with 1 <= low <= high <= "
                              f"{1 + len(names.BYSTANDERS)}, got {people!r}")
        self.people = (n_lo, n_hi)
        if response_window_s is not None and not (np.isfinite(response_window_s) and response_window_s > 0):
            raise ConfigError(f"response_window_s must be a positive number of seconds or None, got {response_window_s!r}")
        self.response_window_s = None if response_window_s is None else float(response_window_s)
        if not (np.isfinite(look_s) and 0.0 <= look_s <= 2.0):
            raise ConfigError(f"look_s must be 0..2 s, got {look_s!r}")
        self.look_s = float(look_s)
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
        n = int(rng.integers(self.people[0], self.people[1] + 1))
        for _ in range(100):  # a draw whose people or loudspeaker do not fit (walls, spacing) is drawn again
            chair = np.array([rng.uniform(1.5, ROOM_SIZE[0] - 1.5), rng.uniform(1.5, ROOM_SIZE[1] - 1.5)])
            heading = rng.uniform(-180.0, 180.0)
            spots: list[tuple[np.ndarray, float]] = []
            for _ in range(n):
                spot = self._place(rng, chair, heading, [b for _, b in spots])
                if spot is None:
                    break
                spots.append(spot)
            if len(spots) < n:
                continue
            caller = int(rng.integers(n))
            person, person_bearing = spots.pop(caller)
            placed = self._place(rng, chair, heading, [person_bearing], speaker=True)
            if placed is not None:
                speaker = placed[0]
                break
        else:
            raise ConfigError(f"could not place {n} people and the loudspeaker in the room (this is a bug)")
        self.person_bearing_deg = float(person_bearing)
        self.bystander_bearings_deg = [float(b) for _, b in spots]

        def face(p):  # facing the robot
            return math.degrees(math.atan2(chair[1] - p[1], chair[0] - p[0]))

        return scenes.RoomConfig(wheelchair_position=tuple(chair), wheelchair_yaw_deg=float(heading),
                                person_position=tuple(person), person_yaw_deg=face(person),
                                speaker_position=tuple(speaker), speaker_yaw_deg=face(speaker),
                                bystanders=tuple((float(p[0]), float(p[1]), face(p)) for p, _ in spots))

    @staticmethod
    def _place(rng, chair, heading_deg, avoid_bearings, *, speaker: bool = False):
        """A floor point 0.6 m inside the walls at a random bearing (deg, relative to the
        wheelchair's heading) and distance, :data:`APART_DEG` from every bearing of
        ``avoid_bearings``; a person (not ``speaker``) out of view. None if none is found."""
        for _ in range(1000):
            bearing = rng.uniform(-180.0, 180.0)
            dist = rng.uniform(1.3, 2.5) if speaker else rng.uniform(1.4, 2.4)
            if not speaker and abs(bearing) < OUT_OF_VIEW_DEG:
                continue  # people start out of view
            if any(abs(_wrap(math.radians(bearing - b))) < math.radians(APART_DEG) for b in avoid_bearings):
                continue
            a = math.radians(heading_deg + bearing)
            p = chair + dist * np.array([math.cos(a), math.sin(a)])
            if 0.6 <= p[0] <= ROOM_SIZE[0] - 0.6 and 0.6 <= p[1] <= ROOM_SIZE[1] - 0.6:
                return p, bearing
        return None

    def _setup_world(self, model, data, rng) -> None:
        self.found_s: float | None = None
        self.target_onset_s: float | None = None
        self.calls = 0
        self._base_prev: tuple[np.ndarray, float] | None = None
        self._base = np.zeros(3, np.float32)
        self._in_view = False
        self.bystander_heads = names.BYSTANDER_HEAD_BODIES[: len(self.bystander_bearings_deg)]
        self.looked_at: str | None = None
        self._look = (None, 0)  # (who, steps) of the look in progress
        self._before_call: set | None = None
        self._gaze_prev: np.ndarray | None = None
        self.gaze_speed_deg_s = 0.0

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
                self.schedule_sound(f"loudspeaker{i}", label, ev.draw_later("loudspeaker", label), speaker, t,
                                    ev.config.loudspeaker_db, frame="world", detail="loudspeaker")
        self.initial_heading = _yaw(self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)[1])
        self._update_base()
        self._in_view, self._image_uv = self.person_in_view()
        self._update_gaze_speed()

    # -- vision: the geometric check -------------------------------------------------------------
    def person_in_view(self, head_body: str = names.PERSON_HEAD_BODY) -> tuple[bool, tuple[float, float]]:
        """Whether a person's head (default the caller's) is in the right eye camera's field of
        view and not occluded, and where (normalized image coordinates u right, v up, -1..1)."""
        origin, rot = self.view.camera_pose(names.EYE_CAMERAS[1])
        head = self.view.body_pose(head_body)[0]
        d = head - origin
        c = rot.T @ d  # camera frame: x right, y up, looking along -z
        if c[2] >= -1e-6:
            return False, (0.0, 0.0)
        u, v = c[0] / (-c[2]) / self._tan_h, c[1] / (-c[2]) / self._tan_v
        if abs(u) > 1.0 or abs(v) > 1.0:
            return False, (0.0, 0.0)
        return self._unoccluded(origin, head, head_body[: head_body.index("/") + 1]), (float(u), float(v))

    def _unoccluded(self, origin: np.ndarray, target: np.ndarray, prefix: str) -> bool:
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
            if any(name.startswith(p) for p in (names.PERSON, *names.BYSTANDERS)):
                return name.startswith(prefix)  # a person: the one looked for, or another in the way
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
        self._update_gaze_speed()
        if self.outcome != "running":
            return 0.0, True
        if self.look_s == 0.0 and self._in_view:  # the paper's check: in view, at any time
            return self._found("caller")
        heard = self.target_onset_s is not None and self.time_s >= self.target_onset_s
        visible = ["caller"] if self._in_view else []
        visible += [b[:-1] for b, h in zip(names.BYSTANDERS, self.bystander_heads) if self.person_in_view(h)[0]]
        if heard:
            # Whoever is in view when the call starts was not turned to: they count once the
            # gaze has left them and come back.
            self._before_call = set(visible) if self._before_call is None else self._before_call & set(visible)
        who = None
        if heard and self.gaze_speed_deg_s < STILL_DEG_S:
            who = next((v for v in visible if v not in self._before_call), None)
        steps = self._look[1] + 1 if who is not None and who == self._look[0] else (1 if who else 0)
        self._look = (who, steps)
        if who is not None and steps * CONTROL_DT >= self.look_s - 1e-9:
            return self._found(who)
        if heard and self.response_window_s is not None and self.time_s - self.target_onset_s > self.response_window_s:
            self.outcome = "too_late"
            return 0.0, True
        return 0.0, False

    def _found(self, who: str) -> tuple[float, bool]:
        self.looked_at = who
        self.found_s = self.time_s
        self.outcome = "success" if who == "caller" else "wrong_person"
        return (1.0 if who == "caller" else 0.0), True

    def _update_gaze_speed(self) -> None:
        """The right eye's forward axis's angular speed in the world (deg/s) over the last step."""
        forward = -self.view.camera_pose(names.EYE_CAMERAS[1])[1][:, 2]
        if self._gaze_prev is not None:
            c = float(np.clip(np.dot(forward, self._gaze_prev), -1.0, 1.0))
            self.gaze_speed_deg_s = math.degrees(math.acos(c)) / CONTROL_DT
        self._gaze_prev = forward

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
            "people": 1 + len(self.bystander_bearings_deg),
            "looked_at": self.looked_at,
            "bystander_bearings_deg": list(self.bystander_bearings_deg),
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
