"""ParkingBrake: pull the brake and let go when its ratchet is heard from the right."""

from __future__ import annotations

import numpy as np

from acoustic_sim.acoustics.sounds.cutting import ratchet_clicks
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE
from acoustic_sim.world import names
from tasks.cabin import CabinLeverTask


def relay_ticks(rng: np.random.Generator, seconds: float, period_s: float) -> np.ndarray:
    """A turn-signal relay: one click every ``period_s`` (the relay closing and opening),
    ``seconds`` long, unit RMS. The clicks are a ratchet's (:func:`ratchet_clicks`), which
    is what a relay sounds like to an ear that knows six classes."""
    clicks = ratchet_clicks(rng)
    n = round(seconds * SAMPLE_RATE)
    x = np.zeros(n)
    t, k = 0, 0
    while t < n:
        c = clicks[k % len(clicks)] * (1.0 if k % 2 == 0 else 0.6)  # closing louder than opening
        m = min(c.size, n - t)
        x[t : t + m] += c[:m]
        t += round(period_s * SAMPLE_RATE * (1.0 + 0.02 * rng.standard_normal()))
        k += 1
    return x / np.sqrt(np.mean(x**2))


class ParkingBrakeEnv(CabinLeverTask):
    """The paper's parking-brake task: the robot pulls the brake lever and lets go when it
    hears the ratchet it operates, on its right, and not a click from elsewhere.

    Description
    -----------
    The robot sits in the driver's seat of the car cabin (scene ``cabin``) with its right hand
    closed on the parking brake's handle, the lever down. Pulling it up, the lever's pins
    pass under the sprung pawl; the pawl's snap behind each tooth is the ratchet's click, at
    the pawl on the robot's right, low (about 110 deg right, 60 deg down). The robot must let
    go once the brake is set, soon after the ratchet is heard. Distractors make the
    *direction* of a click matter: the turn-signal relay ticking at the left front of the
    dashboard (ratchet-like clicks), the ignition key turning, speech from the dashboard
    radio, and engine and road noise (the cabin's diffuse background, 40-55 dB SPL). The
    action and observation spaces are ReverseAlarm's: the right hand holds the brake.

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
    Brake down (tooth 0), gear P, the right hand holding the brake handle (the taught pose,
    settled), after 0.5 s of listening (as in ReverseAlarm). Per episode: the background
    level, and each distractor with its probability: the turn-signal relay (0.6; ticking
    every 0.33-0.4 s from 0.1-1.2 s for 2-4 s, 60-66 dB at 1 m), a key turn (0.4; 0.2-1.5 s),
    radio speech (0.5; 0-2 s).

    Episode End
    -----------
    The target sound is the click of tooth ``required_teeth`` (the first click that sets the
    brake on that many teeth). Terminated when the right hand lets go: ``success`` if the
    lever rests on at least ``required_teeth`` teeth and the target click came at most
    ``success_window_s`` before; else ``early`` (before the target click: a false release),
    ``not_set`` (the lever below ``required_teeth``) or ``late``. Terminated without a
    release: ``no_release`` (``release_timeout_s`` after the target click). Truncated
    (``timeout``) after ``max_episode_s``. ``info``: outcome,
    ``success``, ``false_release``, ``target_onset_s``, ``release_s``, ``reaction_s``,
    ``teeth``, ``brake_deg``, the sounds playing with their true directions, the events.

    Arguments
    ---------
    ``required_teeth`` (int, default 1): teeth the brake must hold on, 1-7.
    ``success_window_s`` (float, default 0.5): longest click-to-release time of a success, s.
    ``release_timeout_s`` (float, default 5.0): no release this long after the click fails, s.
    ``distractors`` (bool, default True): schedule the distractors.
    ``render_mode`` (str | None, default None): ``"rgb_array"`` for :meth:`render`.
    ``profile`` (str, default "paper"): auditory models, ``"paper"`` or ``"fast"``.
    ``hrtf`` (str, default "kemar"): the ears.
    ``max_episode_s`` (float | None, default None): truncation time in s (None: 10 s).
    ``action_mode`` (str, default "joints"): ``"joints"`` or ``"skill"`` (see Action Space).
    ``reward_mode`` (str, default "sparse"): ``"sparse"`` or ``"shaped"`` (see Rewards).
    ``audio_obs`` (bool, default False): add ``audio``.
    ``spectra_obs`` (bool, default False): add ``spectra``.
    ``image_obs`` (bool, default False): add ``image``.
    ``image_size`` (tuple, default (120, 160)): (height, width) of ``image``, pixels.
    ``torch_threads`` (int | None, default 1): torch threads while the pipeline runs.
    """

    task = "parking-brake"
    side = "right"
    specificity = 0.0
    """Off: the ratchet's bins (205 of the paper bank's band) take any click, so the rule
    tells nothing here, and judging an onset by the energy it added waits up to a frame.
    Measurements: docs/notes/cabin_settings.md."""
    fusion = "sum"
    """The paper's sum over bins, not the product (:data:`acoustic_sim.auditory.ssdenet.FUSIONS`):
    the turn-signal relay's ticks are click-like, so the ratchet class hears them too; the
    product places them well (at the relay) and their evidence then competes with the
    ratchet's click in the direction window, where under the sum the click's confident bins
    win. Measurements: docs/notes/cabin_settings.md."""
    default_max_episode_s = 10.0
    relay_probability = 0.6
    relay_start_s = (0.1, 1.2)
    """Range (s after the episode's start) of the turn-signal relay's first tick."""
    key_probability = 0.4
    key_start_s = (0.2, 1.5)
    """Range (s after the episode's start) of the key turn."""
    radio_probability = 0.5
    radio_start_s = (0.0, 2.0)
    relay_position = (1.45, 1.38, 0.66)
    """Room-frame point (m) of the turn-signal relay: under the dashboard, left front."""

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, action_mode: str = "joints", reward_mode: str = "sparse",
                 required_teeth: int = 1, success_window_s: float = 0.5,
                 release_timeout_s: float = 5.0, distractors: bool = True, audio_obs: bool = False,
                 spectra_obs: bool = False, image_obs: bool = False, image_size: tuple = (120, 160),
                 torch_threads: int | None = 1) -> None:
        n = len(names.BRAKE_TOOTH_ANGLES_DEG)
        if not isinstance(required_teeth, (int, np.integer)) or not 1 <= required_teeth <= n:
            raise ConfigError(f"required_teeth must be an integer 1..{n}, got {required_teeth!r}")
        self.required_teeth = int(required_teeth)
        super().__init__(success_window_s=success_window_s, release_timeout_s=release_timeout_s, distractors=distractors,
                         render_mode=render_mode, profile=profile, hrtf=hrtf, max_episode_s=max_episode_s,
                         action_mode=action_mode, reward_mode=reward_mode,
                         audio_obs=audio_obs, spectra_obs=spectra_obs, image_obs=image_obs, image_size=image_size,
                         torch_threads=torch_threads)

    # -- distractors ------------------------------------------------------------------------------
    def _draw_distractors(self, rng: np.random.Generator) -> dict:
        return {
            "relay": rng.random() < self.relay_probability,
            "relay_start": rng.uniform(*self.relay_start_s),
            "relay_len": rng.uniform(2.0, 4.0),
            "relay_period": rng.uniform(0.33, 0.4),
            "relay_db": rng.uniform(60.0, 66.0),
            "key": rng.random() < self.key_probability,
            "key_start": rng.uniform(*self.key_start_s),
        }

    def _play_distractors(self, plan: dict, rng: np.random.Generator) -> None:
        if plan["relay"]:
            signal = relay_ticks(rng, plan["relay_len"], plan["relay_period"])
            self.schedule_sound("relay", "ratchet", signal, self.relay_position, plan["relay_start"], plan["relay_db"],
                                detail="turn-signal relay, left front")
        if plan["key"]:
            self.coupling.events.schedule_key_turn(self.at(plan["key_start"]))

    # -- the lever --------------------------------------------------------------------------------
    def _is_target(self, event: dict) -> bool:
        return event["kind"] == "ratchet_click" and event["detail"] == str(self.required_teeth)

    def _lever_state(self) -> dict:
        return {"teeth": int(self.view.brake_teeth_engaged()), "brake_deg": float(np.rad2deg(self.view.brake_angle()))}

    def _progress(self) -> float:
        return self.view.brake_angle() / np.deg2rad(names.BRAKE_TOOTH_ANGLES_DEG[self.required_teeth - 1])

    def _release_fault(self, state: dict) -> str | None:
        return "not_set" if state["teeth"] < self.required_teeth else None


__all__ = ["ParkingBrakeEnv", "relay_ticks"]
