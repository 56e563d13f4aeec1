"""CallResponse: a person calls the robot on its wheelchair; turn until the person is in view.

The crowd's placement, the field-of-view check and the look rule are :mod:`tasks.crowd`.
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names
from tasks.base import CONTROL_DT, HearingTaskEnv
from tasks.crowd import APART_DEG, LOOK_S, OUT_OF_VIEW_DEG, ROOM_SIZE, STILL_DEG_S, Look, Sight, place_crowd, wrap, yaw_of
from tasks.skills import TurnSkill

FACING_WEIGHT = 0.3
"""Shaped reward: weight of the facing potential (:meth:`CallResponseEnv._reward_terms`)."""

TIME_WEIGHT = 0.3
"""Shaped reward: what a whole episode's time costs."""

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

    Action Space
    ------------
    ``action_mode="joints"``: ``Box(-1, 1, (16,), float32)``, normalized targets; -1 and +1 are
    the ends of the range.

    ====  ========================  ==========  =====
    idx   channel                   range       unit
    ====  ========================  ==========  =====
    0     neck_yaw (+ left)         -90 .. 90   deg
    1     neck_pitch (+ nose down)  -45 .. 45   deg
    2     eye_yaw (+ left)          -30 .. 30   deg
    3     eye_pitch                 -25 .. 25   deg
    4     left_shoulder_pitch       -45 .. 170  deg
    5     left_shoulder_roll        -15 .. 120  deg
    6     left_shoulder_yaw         -90 .. 90   deg
    7     left_elbow                0 .. 145    deg
    8     left_wrist                -70 .. 70   deg
    9-13  right arm, same joints    same        deg
    14    left_wheel (+ forward)    -5 .. 5     rad/s
    15    right_wheel (+ forward)   -5 .. 5     rad/s
    ====  ========================  ==========  =====

    Joint targets drive position servos (the ranges are the actuators' control ranges);
    ``env.unwrapped.layout`` converts physical targets to actions. The wheels (0.30 m radius,
    0.60 m apart) are velocity servos: equal speeds drive, opposite speeds turn on the spot
    (right wheel forward turns left, 1 rad/s each way = 57 deg/s).

    ``action_mode="skill"``: ``Box(-1, 1, (2,), float32)``; the zero action keeps everything as
    it is (nothing moves, nothing lets go), the rest of the robot holds its rest pose
    (:mod:`tasks.skills`).

    ===  =============  =======  =====================================================
    idx  component      range    meaning
    ===  =============  =======  =====================================================
    0    neck_yaw_rate  -1 .. 1  neck yaw rate, x 90 deg/s (+ left), within its range
    1    turn_rate      -1 .. 1  wheelchair turn rate on the spot, x 90 deg/s (+ left)
    ===  =============  =======  =====================================================

    Observation Space
    -----------------
    ``Dict``:

    ===============  =========  ===================================================================
    key              shape      meaning
    ===============  =========  ===================================================================
    joint_pos        (14,)      rad: neck yaw, pitch; eye yaw, pitch; left arm 5; right arm 5
    joint_vel        (14,)      rad/s, same order (clipped to +-50)
    base             (3,)       the wheelchair's odometry: heading since the start (rad, +-pi, +
                                left), forward speed (m/s), yaw rate (rad/s)
    class_prob       (6,)       the percept's fused class probabilities (car_horn, reverse_alarm,
                                ratchet, gearshift, key_turning, human_voice)
    class_dir        (18,)      per class, the estimated direction (unit vector, head frame: x
                                forward, y left, z up), class k in entries 3k..3k+2; zeros when the
                                class has no estimate
    class_conf       (6,)       per class, the estimate's confidence 0..1 (0: no estimate)
    tracked_dir      (18,)      per class, the world-frame tracker's direction seen from the head
                                now (unit vector, head frame), from every frame heard this episode;
                                zeros before any
    tracked_conf     (6,)       per class, the tracker's posterior mass near its peak 0..1 (0:
                                nothing heard yet)
    tracked_decided  (6,)       per class, 1 when the tracker has decided front from back (a head
                                turn moved the mirror image away), else 0
    existence        (D,)       SSDENet existence map of the most likely class that has an
                                estimate, over the D (327) grid directions; zeros if none
    audio            (2, 706)   optional (``audio_obs``): the digital ear block, full scale
    spectra          (2, 1025)  optional (``spectra_obs``): |X|^2 of the ear frame, full scale
    image            (H, W, 3)  optional (``image_obs``): the right eye camera, uint8
    ===============  =========  ===================================================================

    Rewards
    -------
    ``reward_mode="sparse"``: +1 when the caller is looked at, 0 otherwise (``wrong_person``,
    ``too_late``, ``timeout``).

    ``reward_mode="shaped"``: the sum of the terms that ``info`` reports each step in both
    modes: ``reward_outcome`` (the sparse reward), ``reward_facing`` (the change of 0.3 x (1 -
    the angle between the head's forward and the person / 180 deg): a potential, summing over an
    episode to within +-0.3) and ``reward_time`` (-0.3 / the episode's step limit each step). A
    success returns at least 0.4, a failure at most 0.3.

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
    ``render_mode`` (str | None, default None): ``"rgb_array"`` for :meth:`render`.
    ``profile`` (str, default "paper"): auditory models, ``"paper"`` or ``"fast"``.
    ``hrtf`` (str, default "kemar"): the ears.
    ``max_episode_s`` (float | None, default None): truncation time in s (None: 30 s).
    ``action_mode`` (str, default "joints"): ``"joints"`` or ``"skill"`` (see Action Space).
    ``reward_mode`` (str, default "sparse"): ``"sparse"`` or ``"shaped"`` (see Rewards).
    ``audio_obs`` (bool, default False): add ``audio``.
    ``spectra_obs`` (bool, default False): add ``spectra``.
    ``image_obs`` (bool, default False): add ``image``.
    ``image_size`` (tuple, default (120, 160)): (height, width) of ``image``, pixels.
    ``torch_threads`` (int | None, default 1): torch threads while the pipeline runs.
    """

    task = "call-response"
    scene_name = "room"
    default_max_episode_s = 30.0
    background_db_range = (35.0, 45.0)
    speech_probability = 0.8
    other_probability = 0.4
    WHEEL_RADIUS_M = 0.30
    TRACK_M = 0.60

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

    # -- episode ------------------------------------------------------------------------------
    def _scene_config(self, rng: np.random.Generator):
        config, self.person_bearing_deg, self.bystander_bearings_deg = place_crowd(rng, self.people)
        return config

    def _setup_world(self, model, data, rng) -> None:
        self.found_s: float | None = None
        self.target_onset_s: float | None = None
        self.calls = 0
        self._base_prev: tuple[np.ndarray, float] | None = None
        self._base = np.zeros(3, np.float32)
        self._in_view = False
        self.bystander_heads = names.BYSTANDER_HEAD_BODIES[: len(self.bystander_bearings_deg)]
        self.looked_at: str | None = None
        self._looking = Look()

    def _schedule(self, rng: np.random.Generator) -> None:
        self.sight = Sight(self.model, self.data, self.view, self.image_size)
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
        self.initial_heading = yaw_of(self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)[1])
        self._update_base()
        self._in_view, self._image_uv = self.person_in_view()
        self.sight.update_gaze_speed(CONTROL_DT)

    # -- vision: the geometric check -------------------------------------------------------------
    def person_in_view(self, head_body: str = names.PERSON_HEAD_BODY) -> tuple[bool, tuple[float, float]]:
        """Whether a person's head (default the caller's) is in the right eye camera's field of
        view and not occluded, and where (:meth:`tasks.crowd.Sight.person_in_view`)."""
        return self.sight.person_in_view(head_body)

    @property
    def gaze_speed_deg_s(self) -> float:
        """The gaze's angular speed (deg/s) over the last step."""
        return self.sight.gaze_speed_deg_s

    # -- odometry ----------------------------------------------------------------------------------
    def _update_base(self) -> None:
        pos, rot = self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)
        yaw = yaw_of(rot)
        if self._base_prev is None:
            speed, rate = 0.0, 0.0
        else:
            p0, y0 = self._base_prev
            dt = 1.0 / self.metadata["render_fps"]
            speed = float(np.dot(pos[:2] - p0[:2], [math.cos(yaw), math.sin(yaw)]) / dt)
            rate = wrap(yaw - y0) / dt
        self._base_prev = (pos, yaw)
        self._base = np.array([wrap(yaw - self.initial_heading), np.clip(speed, -5, 5), np.clip(rate, -10, 10)], np.float32)

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
        self.sight.update_gaze_speed(CONTROL_DT)
        if self.outcome != "running":
            return 0.0, True
        if self.look_s == 0.0 and self._in_view:  # the paper's check: in view, at any time
            return self._found("caller")
        heard = self.target_onset_s is not None and self.time_s >= self.target_onset_s
        visible = ["caller"] if self._in_view else []
        visible += [b[:-1] for b, h in zip(names.BYSTANDERS, self.bystander_heads) if self.person_in_view(h)[0]]
        who, steps = self._looking.update(visible, heard, self.sight.gaze_speed_deg_s < STILL_DEG_S)
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

    def person_direction(self) -> np.ndarray:
        """Ground truth: unit vector (head frame) to the person's head."""
        c = self.coupling
        head = c.frame.to_room(self.view.body_pose(names.PERSON_HEAD_BODY)[0])
        v = (head - c.head_position) @ c.head_rotation
        return (v / np.linalg.norm(v)).astype(np.float32)

    def _task_info(self) -> dict:
        pos, rot = self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)
        person = self.view.body_pose(names.PERSON_HEAD_BODY)[0]
        bearing = math.degrees(wrap(math.atan2(person[1] - pos[1], person[0] - pos[0]) - yaw_of(rot)))
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


__all__ = ["APART_DEG", "CROWD", "LOOK_S", "OUT_OF_VIEW_DEG", "PAPER_ROOM", "RESPONSE_WINDOW_S", "ROOM_SIZE", "STILL_DEG_S",
           "CallResponseEnv"]
