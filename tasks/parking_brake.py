"""ParkingBrake: pull the brake and let go when its ratchet is heard from the right."""

from __future__ import annotations

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE
from acoustic_sim.world import names
from acoustic_sim.world.events import ratchet_clicks
from tasks.base import CabinLeverTask, TaskSound


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
    radio, and engine and road noise (the cabin's diffuse background, 40-55 dB SPL).

    Action Space
    ------------
    As :class:`tasks.reverse_alarm.ReverseAlarmEnv`: ``Box(-1, 1, (16,), float32)``, neck (2),
    eyes (2), left arm (5), right arm (5) joint targets, then ``grasp_left`` and
    ``grasp_right`` (> 0 hold, <= 0 open). The right hand holds the brake.

    Observation Space
    -----------------
    As :class:`tasks.reverse_alarm.ReverseAlarmEnv`: ``joint_pos`` (14,), ``joint_vel``
    (14,), ``grasp`` (2,), ``class_prob`` (6,), ``class_dir`` (6, 3), ``class_conf`` (6,),
    ``existence`` (D,), and optionally ``audio`` (2, 706), ``spectra`` (2, 1025), ``image``.

    Rewards
    -------
    +1 on success, -1 on failure (both at the episode's end), 0 otherwise.

    Starting State
    --------------
    Brake down (tooth 0), gear P, the right hand holding the brake handle (the taught pose,
    settled), after 0.5 s of listening (as in ReverseAlarm). Per episode: the background level, and each distractor with its probability:
    the turn-signal relay (0.6; ticking every 0.33-0.4 s from 0.1-1.2 s for 2-4 s, 60-66 dB
    at 1 m), a key turn (0.4; 0.2-1.5 s), radio speech (0.5; 0-2 s).

    Episode End
    -----------
    The target sound is the click of tooth ``required_teeth`` (the first click that sets the
    brake on that many teeth). Terminated when the right hand lets go: ``success`` if the
    lever rests on at least ``required_teeth`` teeth and the target click came at most
    ``success_window_s`` before; else ``early`` (before the target click: a false release),
    ``not_set`` (the lever below ``required_teeth``) or ``late``. Terminated without a release: ``no_release`` (``release_timeout_s`` after
    the target click). Truncated (``timeout``) after ``max_episode_s``. ``info``: outcome,
    ``success``, ``false_release``, ``target_onset_s``, ``release_s``, ``reaction_s``,
    ``teeth``, ``brake_deg``, the sounds playing with their true directions, the events.

    Arguments
    ---------
    ``render_mode`` (str | None, default None): ``"rgb_array"`` for :meth:`render`.
    ``profile`` (str, default "paper"): auditory models, ``"paper"`` or ``"fast"``.
    ``hrtf`` (str, default "kemar"): the ears.
    ``max_episode_s`` (float | None, default None): truncation time in s (None: 10 s).
    ``required_teeth`` (int, default 1): teeth the brake must hold on, 1-7.
    ``success_window_s`` (float, default 0.5): longest click-to-release time of a success, s.
    ``release_timeout_s`` (float, default 5.0): no release this long after the click fails, s.
    ``distractors`` (bool, default True): schedule the distractors.
    ``audio_obs`` (bool, default False): add ``audio``.
    ``spectra_obs`` (bool, default False): add ``spectra``.
    ``image_obs`` (bool, default False): add ``image``.
    ``image_size`` (tuple, default (120, 160)): (height, width) of ``image``, pixels.
    ``torch_threads`` (int | None, default 1): torch threads while the pipeline runs.
    """

    task = "parking-brake"
    side = "right"
    default_max_episode_s = 10.0
    relay_probability = 0.6
    key_probability = 0.4
    radio_probability = 0.5
    relay_position = (1.45, 1.38, 0.66)
    """Room-frame point (m) of the turn-signal relay: under the dashboard, left front."""

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, required_teeth: int = 1, success_window_s: float = 0.5,
                 release_timeout_s: float = 5.0, distractors: bool = True, audio_obs: bool = False,
                 spectra_obs: bool = False, image_obs: bool = False, image_size: tuple = (120, 160),
                 torch_threads: int | None = 1) -> None:
        n = len(names.BRAKE_TOOTH_ANGLES_DEG)
        if not isinstance(required_teeth, (int, np.integer)) or not 1 <= required_teeth <= n:
            raise ConfigError(f"required_teeth must be an integer 1..{n}, got {required_teeth!r}")
        for what, v in (("success_window_s", success_window_s), ("release_timeout_s", release_timeout_s)):
            if not (np.isfinite(v) and v > 0):
                raise ConfigError(f"{what} must be a positive number of seconds, got {v!r}")
        self.required_teeth = int(required_teeth)
        self.success_window_s = float(success_window_s)
        self.release_timeout_s = float(release_timeout_s)
        self.distractors = bool(distractors)
        super().__init__(render_mode=render_mode, profile=profile, hrtf=hrtf, max_episode_s=max_episode_s,
                         audio_obs=audio_obs, spectra_obs=spectra_obs, image_obs=image_obs, image_size=image_size,
                         torch_threads=torch_threads)

    # -- episode ------------------------------------------------------------------------------
    def _schedule(self, rng: np.random.Generator) -> None:
        relay, relay_start, relay_len = rng.random() < self.relay_probability, rng.uniform(0.1, 1.2), rng.uniform(2.0, 4.0)
        relay_period, relay_db = rng.uniform(0.33, 0.4), rng.uniform(60.0, 66.0)
        key, key_start = rng.random() < self.key_probability, rng.uniform(0.2, 1.5)
        radio, radio_start, radio_db = rng.random() < self.radio_probability, rng.uniform(0.0, 2.0), rng.uniform(60.0, 68.0)
        sound_rng = np.random.default_rng(rng.integers(2**63))
        if not self.distractors:
            return
        if relay:
            self.add_task_sound(TaskSound(
                name="task/relay", label="ratchet", kind="distractor", detail="turn-signal relay, left front",
                signal=relay_ticks(sound_rng, relay_len, relay_period), position=np.array(self.relay_position),
                level_db=relay_db, start=round(self.at(relay_start) * SAMPLE_RATE)))
        if key:
            self.coupling.events.schedule_key_turn(self.at(key_start))
        if radio:
            self.add_radio(sound_rng, radio_start, radio_db)

    def _lever_state(self) -> dict:
        return {"teeth": int(self.view.brake_teeth_engaged()), "brake_deg": float(np.rad2deg(self.view.brake_angle()))}

    def _evaluate(self):
        if self.target_onset_s is None:
            tooth = str(self.required_teeth)
            onset = next((e["time_s"] for e in self.step_events if e["kind"] == "ratchet_click" and e["detail"] == tooth), None)
            if onset is not None:
                self.target_onset_s = float(onset)
        return super()._evaluate()

    def _judge_release(self) -> str:
        if self.false_release:
            return "early"
        if self.released_state["teeth"] < self.required_teeth:
            return "not_set"
        return "success" if self.reaction_s <= self.success_window_s + 1e-9 else "late"

    def _judge_running(self) -> str:
        if self.target_onset_s is not None and self.time_s - self.target_onset_s > self.release_timeout_s:
            return "no_release"
        return "running"


__all__ = ["ParkingBrakeEnv", "relay_ticks"]
