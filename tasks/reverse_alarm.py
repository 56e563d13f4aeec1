"""ReverseAlarm: put the car into reverse and let go when the reverse alarm sounds in front."""

from __future__ import annotations

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.errors import ConfigError
from acoustic_sim.world import scenes
from acoustic_sim.world.events import EventsConfig
from tasks.cabin import CabinLeverTask

HIDDEN_VARIATION = {"reverse_deg": (7.0, 23.0), "alarm_delay_s": (0.1, 1.5)}
"""The defaults, which hide the decisive moment and place from everything but the ears: R
anywhere in 7-23 deg (its capture zone is 4-9 deg wide, so no fixed lever angle is in R for
half the cars), the alarm 0.1-1.5 s after R engages (a reversing buzzer's relay)."""

SUCCESS_WINDOW_S = 0.4
"""The default success window (s). The hand feels R's detent (:class:`policies.lever_policy.
DetentFeel`), so a deaf policy knows when R engaged and lacks only the relay's latency: letting
go a fixed time after the feel succeeds for a share window / 1.4 s of the latencies at best
(0.71 with a 1 s window, 0.29 with 0.4 s); a listening policy reacts in about 0.1 s.
Measurements: docs/notes/deaf_baseline.md."""

PAPER_CAR = {"reverse_deg": (15.0, 15.0), "alarm_delay_s": (0.0, 0.0), "success_window_s": 1.0}
"""Arguments for the paper's car: R at 15 deg, the alarm at once, a 1 s window (the setting
before the hidden car; the lever angle and a clock tell all)."""


def _range(what: str, value, limits: tuple, unit: str) -> tuple[float, float]:
    """A (low, high) range within ``limits``, as floats."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a (low, high) pair of numbers ({unit}), got {value!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and limits[0] <= lo <= hi <= limits[1]):
        raise ConfigError(f"{what} must satisfy {limits[0]:g} <= low <= high <= {limits[1]:g} ({unit}), got {value!r}")
    return lo, hi


class ReverseAlarmEnv(CabinLeverTask):
    """The paper's gearshift task: the robot pushes the gearshift into R and lets go when it
    hears the reverse alarm it set off, in front of it, and not some other beeper.

    Description
    -----------
    The robot sits in the driver's seat of the car cabin (scene ``cabin``) with its left hand
    closed on the gear knob, the lever in P. Pushing the lever toward D, it enters R (15 deg),
    and the car's reverse alarm starts beeping from the dashboard speaker, about 0.8 m in
    front of the head (the ``alarm_start`` event). The robot must let go of the lever while it
    is in R and soon after the alarm starts. Distractors make the *direction* of the beeping
    matter, not only its class: another vehicle's reverse alarm behind or beside the car
    (outside; through the car body), a car horn outside, speech from the dashboard radio, and
    engine and road noise (the cabin's diffuse background, 40-55 dB SPL per episode). The ears
    hear all of it, with the robot's own motor noise, through the auditory pipeline.

    Action Space
    ------------
    ``action_mode="joints"``: ``Box(-1, 1, (16,), float32)``, normalized targets; -1 and +1 are
    the ends of the range.

    ====  ========================  ==========  ===================
    idx   channel                   range       unit
    ====  ========================  ==========  ===================
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
    14    grasp_left                -1 .. 1     > 0 hold, <= 0 open
    15    grasp_right               -1 .. 1     > 0 hold, <= 0 open
    ====  ========================  ==========  ===================

    Joint targets drive position servos (the ranges are the actuators' control ranges);
    ``env.unwrapped.layout`` converts physical targets to actions. A grasp command > 0 closes an
    open hand on its lever if the palm is within 5 cm of the handle; <= 0 opens it.

    ``action_mode="skill"``: ``Box(-1, 1, (2,), float32)``; the zero action keeps everything as
    it is (nothing moves, nothing lets go), the rest of the robot holds its rest pose
    (:mod:`tasks.skills`).

    ===  ==========  =======  ==================================================================
    idx  component   range    meaning
    ===  ==========  =======  ==================================================================
    0    lever_rate  -1 .. 1  lever speed along the taught motion, x 20 deg/s (+ away from rest)
    1    release     -1 .. 1  > 0.8 for 3 steps in a row opens the hand; else it holds
    ===  ==========  =======  ==================================================================

    Observation Space
    -----------------
    ``Dict``:

    ===============  =========  ===================================================================
    key              shape      meaning
    ===============  =========  ===================================================================
    joint_pos        (14,)      rad: neck yaw, pitch; eye yaw, pitch; left arm 5; right arm 5
    joint_vel        (14,)      rad/s, same order (clipped to +-50)
    grasp            (2,)       1 if the left / right hand holds its lever
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
    ``reward_mode="sparse"``: +1 on success, -1 on failure, the time limit included (both at the
    episode's end), 0 otherwise.

    ``reward_mode="shaped"``: the sum of the terms that ``info`` reports each step in both
    modes: ``reward_outcome`` (the sparse reward), ``reward_progress`` (the change of 0.3 x the
    lever's progress toward the position the task asks for, 0 at rest, 1 there: a potential, so
    over an episode it sums to at most 0.3) and ``reward_timing`` (on success, 0.5 x (1 -
    reaction / success_window_s)). A success returns at least 1, a failure at most -0.7.

    Starting State
    --------------
    Gear P, brake down, the robot in its seated rest pose with the left hand holding the gear
    knob (the taught pose at the lever's rest angle, settled). The ears listen for 0.5 s before
    the first observation (the pipeline's 0.4 s window fills with the cabin's own sound, which
    also calibrates the noise reference); times below count from the first observation. Per
    episode (from the seed): the background level, and each distractor with its probability:
    another vehicle's beeper (0.6; behind or beside, 2-6 m from the car, starting 0.3-2.5 s,
    1.5-3 s long), a car horn (0.4; 0.3-3 s), radio speech (0.5; 0-2.5 s).

    Episode End
    -----------
    Terminated when the left hand lets go: ``success`` if the lever is in R and the alarm
    started at most ``success_window_s`` before; else ``early`` (before the alarm: a false
    release), ``late`` or ``not_in_reverse``. Terminated without a release: ``past_reverse``
    (the lever left R toward N) or ``no_release`` (``release_timeout_s`` after the alarm
    started). Truncated (``timeout``) after ``max_episode_s``. ``info`` holds the outcome,
    ``success``, ``false_release``, ``target_onset_s`` (alarm start), ``release_s``,
    ``reaction_s``, ``gear``, the sounds playing with their true directions, the events.

    Arguments
    ---------
    ``success_window_s`` (float, default 0.4): longest alarm-to-release time of a success, s
    (:data:`SUCCESS_WINDOW_S` says why 0.4).
    ``release_timeout_s`` (float, default 5.0): no release this long after the alarm fails, s.
    ``distractors`` (bool, default True): schedule the distractors.
    ``reverse_deg`` ((low, high) deg, default (7, 23)): this car's R detent, drawn uniformly
    per episode within 7..23 deg (:data:`acoustic_sim.world.scenes.REVERSE_DEG_RANGE`); the
    two detent bumps around R move with it. (15, 15) is the paper's car.
    ``alarm_delay_s`` ((low, high) s, default (0.1, 1.5)): the alarm's relay latency after R
    engages, drawn uniformly per episode within 0..5 s; (0, 0) is the paper's (at once).
    Both are hidden: absent from the observation, in ``info["hidden"]``. The defaults
    (:data:`HIDDEN_VARIATION`) are the setting in which the lever angle and a clock no longer
    tell when and where the alarm comes; ``ReverseAlarmEnv(**PAPER_CAR)`` is the paper's car.
    ``render_mode`` (str | None, default None): ``"rgb_array"`` for :meth:`render`.
    ``profile`` (str, default "paper"): auditory models, ``"paper"`` or ``"fast"``.
    ``hrtf`` (str, default "kemar"): the ears.
    ``max_episode_s`` (float | None, default None): truncation time in s (None: 12 s).
    ``action_mode`` (str, default "joints"): ``"joints"`` or ``"skill"`` (see Action Space).
    ``reward_mode`` (str, default "sparse"): ``"sparse"`` or ``"shaped"`` (see Rewards).
    ``audio_obs`` (bool, default False): add ``audio``.
    ``spectra_obs`` (bool, default False): add ``spectra``.
    ``image_obs`` (bool, default False): add ``image``.
    ``image_size`` (tuple, default (120, 160)): (height, width) of ``image``, pixels.
    ``torch_threads`` (int | None, default 1): torch threads while the pipeline runs.
    """

    task = "reverse-alarm"
    side = "left"
    default_max_episode_s = 12.0
    beeper_probability = 0.6
    horn_probability = 0.4
    radio_probability = 0.5
    radio_start_s = (0.0, 2.5)

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, action_mode: str = "joints", reward_mode: str = "sparse",
                 success_window_s: float = SUCCESS_WINDOW_S,
                 release_timeout_s: float = 5.0, distractors: bool = True,
                 reverse_deg: tuple = HIDDEN_VARIATION["reverse_deg"], alarm_delay_s: tuple = HIDDEN_VARIATION["alarm_delay_s"],
                 audio_obs: bool = False, spectra_obs: bool = False, image_obs: bool = False,
                 image_size: tuple = (120, 160), torch_threads: int | None = 1) -> None:
        self.reverse_deg = _range("reverse_deg", reverse_deg, scenes.REVERSE_DEG_RANGE, "deg")
        self.alarm_delay_s = _range("alarm_delay_s", alarm_delay_s, (0.0, 5.0), "s")
        super().__init__(success_window_s=success_window_s, release_timeout_s=release_timeout_s, distractors=distractors,
                         render_mode=render_mode, profile=profile, hrtf=hrtf, max_episode_s=max_episode_s,
                         action_mode=action_mode, reward_mode=reward_mode,
                         audio_obs=audio_obs, spectra_obs=spectra_obs, image_obs=image_obs, image_size=image_size,
                         torch_threads=torch_threads)

    # -- the hidden car ---------------------------------------------------------------------------
    def _draw_hidden(self, rng: np.random.Generator) -> dict:
        # Both are drawn whatever the ranges, so that fixing one does not change the other.
        return {"reverse_deg": float(rng.uniform(*self.reverse_deg)), "alarm_delay_s": float(rng.uniform(*self.alarm_delay_s))}

    def _scene_config(self, rng):
        return scenes.CabinConfig(gear="P", brake_tooth=0, reverse_deg=self.hidden["reverse_deg"])

    def _events_config(self):
        return EventsConfig(alarm_delay_s=self.hidden["alarm_delay_s"])

    # -- distractors ------------------------------------------------------------------------------
    def _draw_distractors(self, rng: np.random.Generator) -> dict:
        return {
            "beeper": rng.random() < self.beeper_probability,
            "where": rng.choice(["behind", "left", "right"], p=[0.5, 0.25, 0.25]),
            "distance": rng.uniform(2.0, 6.0),
            "offset": rng.uniform(-1.0, 1.0),
            "beeper_start": rng.uniform(0.3, 2.5),
            "beeper_len": rng.uniform(1.5, 3.0),
            "beeper_db": rng.uniform(100.0, 107.0),
            "horn": rng.random() < self.horn_probability,
            "horn_start": rng.uniform(0.3, 3.0),
        }

    def _play_distractors(self, plan: dict, rng: np.random.Generator) -> None:
        c = self.coupling
        if plan["beeper"]:
            # Another vehicle, outside the car: room-frame point 2-6 m behind or beside it.
            where, distance, offset = plan["where"], plan["distance"], plan["offset"]
            head = c.head_position
            if where == "behind":
                point = np.array([-distance, head[1] + offset, 0.8])
            else:
                y = c.frame.dimensions[1] + distance if where == "left" else -distance
                point = np.array([head[0] + offset, y, 0.8])
            signal = sounds.generate("reverse_alarm", rng, seconds=plan["beeper_len"])
            self.schedule_sound("beeper", "reverse_alarm", signal, point, plan["beeper_start"], plan["beeper_db"],
                                outside=True, detail=f"another vehicle's beeper, {where}")
        if plan["horn"]:
            c.events.schedule_horn(self.at(plan["horn_start"]))

    # -- the lever --------------------------------------------------------------------------------
    def _is_target(self, event: dict) -> bool:
        return event["kind"] == "alarm_start"

    def _lever_state(self) -> dict:
        return {"gear": self.view.gearshift_position() or "", "gear_deg": float(np.rad2deg(self.view.gearshift_angle()))}

    def _release_fault(self, state: dict) -> str | None:
        return None if state["gear"] == "R" else "not_in_reverse"

    def _progress(self) -> float:
        g = self.view.gearshift_geometry
        r = g.names.index("R")
        # A triangle that peaks at R's detent: pushing on past R undoes the progress.
        reverse = g.detents_rad[r]
        return 1.0 - abs(self.view.gearshift_angle() - reverse) / reverse

    def _past_reverse(self) -> bool:
        g = self.view.gearshift_geometry
        r = g.names.index("R")
        return self.view.gearshift_angle() > g.detents_rad[r] + g.release_rad[r]

    def _judge_running(self) -> str:
        if self._past_reverse():
            return "past_reverse"
        return super()._judge_running()


__all__ = ["HIDDEN_VARIATION", "PAPER_CAR", "ReverseAlarmEnv", "SUCCESS_WINDOW_S"]
