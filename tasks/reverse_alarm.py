"""ReverseAlarm: put the car into reverse and let go when the reverse alarm sounds in front."""

from __future__ import annotations

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.frames import SAMPLE_RATE
from tasks.base import CabinLeverTask, TaskSound, outside_placement


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
    ``Box(-1, 1, (16,), float32)``: normalized targets; -1 and +1 are the ends of the range.

    ===  ==========================  ===============  =====
    idx  channel                     range            unit
    ===  ==========================  ===============  =====
    0    neck_yaw (+ left)           -90 .. 90        deg
    1    neck_pitch (+ nose down)    -45 .. 45        deg
    2    eye_yaw (+ left)            -30 .. 30        deg
    3    eye_pitch                   -25 .. 25        deg
    4    left_shoulder_pitch         -45 .. 170       deg
    5    left_shoulder_roll          -15 .. 120       deg
    6    left_shoulder_yaw           -90 .. 90        deg
    7    left_elbow                  0 .. 145         deg
    8    left_wrist                  -70 .. 70        deg
    9-13 right arm, same joints      same             deg
    14   grasp_left                  > 0 hold, <= 0   open
    15   grasp_right                 > 0 hold, <= 0   open
    ===  ==========================  ===============  =====

    Joint targets drive position servos (the ranges are the actuators' control ranges).
    A grasp command > 0 closes an open hand on its lever if the palm is within 5 cm of the
    handle; <= 0 opens it. ``env.unwrapped.layout`` converts physical targets (rad) to actions.

    Observation Space
    -----------------
    ``Dict``:

    ============  ==========  ===================================================================
    key           shape       meaning
    ============  ==========  ===================================================================
    joint_pos     (14,)       rad: neck yaw, pitch; eye yaw, pitch; left arm 5; right arm 5
    joint_vel     (14,)       rad/s, same order (clipped to +-50)
    grasp         (2,)        1 if the left / right hand holds its lever
    class_prob    (6,)        the percept's fused class probabilities (car_horn, reverse_alarm,
                              ratchet, gearshift, key_turning, human_voice)
    class_dir     (6, 3)      per class, the estimated direction (unit vector, head frame: x
                              forward, y left, z up); zeros when the class has no estimate
    class_conf    (6,)        per class, the estimate's confidence 0..1 (0: no estimate)
    existence     (D,)        SSDENet existence map of the most likely class that has an
                              estimate, over the D (327) grid directions; zeros if none
    audio         (2, 706)    optional (``audio_obs``): the digital ear block, full scale
    spectra       (2, 1025)   optional (``spectra_obs``): |X|^2 of the ear frame, full scale
    image         (H, W, 3)   optional (``image_obs``): the right eye camera, uint8
    ============  ==========  ===================================================================

    Rewards
    -------
    +1 on success, -1 on failure (both at the episode's end), 0 otherwise.

    Starting State
    --------------
    Gear P, brake down, the robot in its seated rest pose with the left hand holding the gear
    knob (the taught pose at the lever's rest angle, settled). The ears listen for 0.5 s before
    the first observation (the pipeline's 0.4 s window fills with the cabin's own sound, which
    also calibrates the noise reference); times below count from the first observation. Per episode (from the seed):
    the background level, and each distractor with its probability: another vehicle's
    beeper (0.6; behind or beside, 2-6 m from the car, starting 0.3-2.5 s, 1.5-3 s long),
    a car horn (0.4; 0.3-3 s), radio speech (0.5; 0-2.5 s).

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
    ``render_mode`` (str | None, default None): ``"rgb_array"`` for :meth:`render`.
    ``profile`` (str, default "paper"): auditory models, ``"paper"`` or ``"fast"``.
    ``hrtf`` (str, default "kemar"): the ears.
    ``max_episode_s`` (float | None, default None): truncation time in s (None: 12 s).
    ``success_window_s`` (float, default 1.0): longest alarm-to-release time of a success, s.
    ``release_timeout_s`` (float, default 5.0): no release this long after the alarm fails, s.
    ``distractors`` (bool, default True): schedule the distractors.
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

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, success_window_s: float = 1.0, release_timeout_s: float = 5.0,
                 distractors: bool = True, audio_obs: bool = False, spectra_obs: bool = False, image_obs: bool = False,
                 image_size: tuple = (120, 160), torch_threads: int | None = 1) -> None:
        from acoustic_sim.errors import ConfigError

        for what, v in (("success_window_s", success_window_s), ("release_timeout_s", release_timeout_s)):
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"{what} must be a positive number of seconds, got {v!r}")
        self.success_window_s = float(success_window_s)
        self.release_timeout_s = float(release_timeout_s)
        self.distractors = bool(distractors)
        super().__init__(render_mode=render_mode, profile=profile, hrtf=hrtf, max_episode_s=max_episode_s,
                         audio_obs=audio_obs, spectra_obs=spectra_obs, image_obs=image_obs, image_size=image_size,
                         torch_threads=torch_threads)

    # -- episode ------------------------------------------------------------------------------
    def _schedule(self, rng: np.random.Generator) -> None:
        # Draw every distractor's choices whether or not it plays, so that one distractor's
        # presence does not change another's draw.
        beeper = rng.random() < self.beeper_probability
        where = rng.choice(["behind", "left", "right"], p=[0.5, 0.25, 0.25])
        distance = rng.uniform(2.0, 6.0)
        offset = rng.uniform(-1.0, 1.0)
        beeper_start, beeper_len, beeper_db = rng.uniform(0.3, 2.5), rng.uniform(1.5, 3.0), rng.uniform(100.0, 107.0)
        horn, horn_start = rng.random() < self.horn_probability, rng.uniform(0.3, 3.0)
        radio, radio_start, radio_db = rng.random() < self.radio_probability, rng.uniform(0.0, 2.5), rng.uniform(60.0, 68.0)
        sound_rng = np.random.default_rng(rng.integers(2**63))
        if not self.distractors:
            return
        c = self.coupling
        head = c.head_position
        dims = c.frame.dimensions
        if beeper:
            if where == "behind":
                point = np.array([-distance, head[1] + offset, 0.8])
            else:
                y = dims[1] + distance if where == "left" else -distance
                point = np.array([head[0] + offset, y, 0.8])
            position, level = outside_placement(c, point, beeper_db)
            self.add_task_sound(TaskSound(
                name="task/beeper", label="reverse_alarm", kind="distractor", detail=f"another vehicle's beeper, {where}",
                signal=sounds.generate("reverse_alarm", sound_rng, seconds=beeper_len), position=position, level_db=level,
                start=round(self.at(beeper_start) * SAMPLE_RATE)))
        if horn:
            c.events.schedule_horn(self.at(horn_start))
        if radio:
            self.add_radio(sound_rng, radio_start, radio_db)

    def _lever_state(self) -> dict:
        return {"gear": self.view.gearshift_position() or "", "gear_deg": float(np.rad2deg(self.view.gearshift_angle()))}

    def _past_reverse(self) -> bool:
        g = self.view.gearshift_geometry
        r = g.names.index("R")
        return self.view.gearshift_angle() > g.detents_rad[r] + g.release_rad[r]

    def _evaluate(self):
        if self.target_onset_s is None:
            onset = next((e["time_s"] for e in self.step_events if e["kind"] == "alarm_start"), None)
            if onset is not None:
                self.target_onset_s = float(onset)
        return super()._evaluate()

    def _judge_release(self) -> str:
        gear = self.released_state["gear"]
        if self.false_release:
            return "early"
        if gear != "R":
            return "not_in_reverse"
        return "success" if self.reaction_s <= self.success_window_s + 1e-9 else "late"

    def _judge_running(self) -> str:
        if self._past_reverse():
            return "past_reverse"
        if self.target_onset_s is not None and self.time_s - self.target_onset_s > self.release_timeout_s:
            return "no_release"
        return "running"


__all__ = ["ReverseAlarmEnv"]
