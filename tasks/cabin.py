"""What the two cabin tasks share: a hand on a lever, let go on the right sound.

ReverseAlarm (the left hand on the gearshift) and ParkingBrake (the right hand on the brake)
are one task with two levers: the hand starts closed on its lever; the lever's own mechanism
makes the target sound (the reverse alarm entering R, the ratchet's click of the required
tooth); the episode ends when the hand lets go, a success if the lever is where it should be
and the target sound came at most ``success_window_s`` before. Distractors (each task's
own, and the dashboard radio that both have) make the direction of a sound matter.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from acoustic_sim.acoustics import sounds
from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scenes
from tasks.actions import ActionChannel
from tasks.base import HearingTaskEnv
from tasks.levers import hold_lever
from tasks.skills import LeverSkill
from tasks.task_sounds import TaskSound

PROGRESS_WEIGHT = 0.3
"""Shaped reward: weight of the lever's progress potential (:meth:`CabinLeverTask._reward_terms`)."""

TIMING_WEIGHT = 0.5
"""Shaped reward: bonus of a success at once (none at the end of the window)."""


class CabinLeverTask(HearingTaskEnv):
    """A cabin task in which one hand starts on its lever and the episode ends when it lets go.

    Subclasses set :attr:`side` and their distractors' parameters, and implement
    :meth:`_is_target`, :meth:`_lever_state`, :meth:`_release_fault`,
    :meth:`_draw_distractors` and :meth:`_play_distractors` (and may extend
    :meth:`_judge_running`).

    Parameters
    ----------
    success_window_s : float
        Longest time (s, > 0) from the target sound's start to the release of a success.
    release_timeout_s : float
        The episode fails when the hand still holds this long (s, > 0) after the target sound.
    distractors : bool
        Schedule the distractors.
    **kwargs
        The arguments of :class:`~tasks.base.HearingTaskEnv`.
    """

    scene_name = "cabin"
    side = "left"
    background_db_range = (40.0, 55.0)
    """Engine idling and road noise: the cabin's diffuse background, dB SPL per episode."""
    coverage = 0.5
    """Attribution: in the cabin the radio, the key turn and the gearshift's clunk start while
    the ratchet or the alarm class is heard; a frame counts for a class only when it covers
    half of the class's bins (:mod:`acoustic_sim.auditory.pipeline`). The room task keeps 0:
    speech frames often cover fewer than half of the voice's bins. Measurements:
    docs/notes/cabin_settings.md."""
    specificity = 0.2
    """Attribution, second rule: a frame counts for a class only when a fifth of the energy
    its onset added lies in the class's bins (:mod:`acoustic_sim.auditory.pipeline`). A car
    horn outside starting while another vehicle's beeper is heard as the reverse alarm lit up
    the alarm's bins and put the "alarm" in front (an early release). ReverseAlarm only
    (ParkingBrake turns it off, :attr:`tasks.parking_brake.ParkingBrakeEnv.specificity`).
    Measurements: docs/notes/cabin_settings.md."""
    onset_windows = 3
    """Precedence: the reverse alarm's beeps ramp up over 2-8 ms and each gives one onset, so
    one direction sample per beep (0.8-1.1 s apart: a first beep placed wrong makes the
    release late). At a rising onset the pipeline takes three first-wavefront windows, 1 ms
    apart, and averages their maps per bin (:mod:`acoustic_sim.auditory.precedence`);
    clicks (falling energy) keep one. Measurements: docs/notes/cabin_settings.md."""
    radio_position = (1.62, 0.78, 0.72)
    """Room-frame point (m) of the dashboard radio's loudspeaker (front, a little right)."""
    radio_probability = 0.5
    """Probability that the radio plays speech in an episode."""
    radio_start_s = (0.0, 2.5)
    """Range (s after the episode's start) of the radio's start."""
    radio_db = (60.0, 68.0)
    """Range (dB SPL at 1 m) of the radio's level."""
    timeout_reward = -1.0
    """Holding on to the limit fails the task too: at 0 a learner learns to keep still (PPO on
    ReverseAlarm timed out in 212 of 437 episodes; docs/notes/learned_policies.md)."""

    def __init__(self, *, success_window_s: float, release_timeout_s: float, distractors: bool, **kwargs) -> None:
        for what, v in (("success_window_s", success_window_s), ("release_timeout_s", release_timeout_s)):
            if not (isinstance(v, (int, float, np.integer, np.floating)) and np.isfinite(v) and v > 0):
                raise ConfigError(f"{what} must be a positive number of seconds, got {v!r}")
        self.success_window_s = float(success_window_s)
        self.release_timeout_s = float(release_timeout_s)
        self.distractors = bool(distractors)
        super().__init__(**kwargs)

    # -- hooks of the task -----------------------------------------------------------------------
    def _is_target(self, event: dict) -> bool:
        """Whether an event record of this step is the target sound's start."""
        raise NotImplementedError

    def _lever_state(self) -> dict:
        """The lever's state for ``info`` (and for judging a release)."""
        raise NotImplementedError

    def _release_fault(self, state: dict) -> str | None:
        """The outcome of a release after the target sound with the lever in ``state``
        (:meth:`_lever_state` at the release) if the lever is not where it should be, else None."""
        raise NotImplementedError

    def _progress(self) -> float:
        """The lever's progress toward the position the task asks for: 0 at rest, 1 there
        (ground truth, for the shaped reward only)."""
        raise NotImplementedError

    def _draw_distractors(self, rng: np.random.Generator) -> dict:
        """Draw every choice of the task's own distractors (whether or not they play)."""
        raise NotImplementedError

    def _play_distractors(self, plan: dict, rng: np.random.Generator) -> None:
        """Schedule the task's own distractors drawn by :meth:`_draw_distractors`; ``rng``
        draws their sounds."""
        raise NotImplementedError

    # -- episode ---------------------------------------------------------------------------------
    def _scene_config(self, rng):
        return scenes.CabinConfig(gear="P", brake_tooth=0)

    def _setup_world(self, model, data, rng) -> None:
        hold_lever(model, data, self.side)
        self.target_onset_s: float | None = None
        self.release_s: float | None = None
        self.released_state: dict | None = None
        self.false_release = False
        self.reaction_s: float | None = None

    def _schedule(self, rng: np.random.Generator) -> None:
        # Every distractor's choices are drawn whether or not it plays (and with distractors
        # off), so that one distractor's presence does not change another's draw.
        plan = self._draw_distractors(rng)
        radio = rng.random() < self.radio_probability
        radio_start, radio_db = rng.uniform(*self.radio_start_s), rng.uniform(*self.radio_db)
        sound_rng = np.random.default_rng(rng.integers(2**63))
        if not self.distractors:
            return
        self._play_distractors(plan, sound_rng)
        if radio:
            self.add_radio(sound_rng, radio_start, radio_db)

    def add_radio(self, rng: np.random.Generator, start_s: float, level_db: float) -> TaskSound:
        """Speech from the dashboard radio (``human_voice``) ``start_s`` after the episode's
        start, at ``level_db`` (dB SPL at 1 m); ``rng`` draws the speech."""
        return self.schedule_sound(f"radio{len(self.task_sounds)}", "human_voice", sounds.generate("human_voice", rng),
                                   self.radio_position, start_s, level_db, detail="radio")

    def _apply_special(self, channel: ActionChannel, value: float) -> None:
        side = channel.target.split(":", 1)[1]
        holding = scenes.is_grasping(self.model, self.data, side)
        if value > 0.0 and not holding:
            scenes.grasp(self.model, self.data, side)
        elif value <= 0.0 and holding:
            scenes.release(self.model, self.data, side)
            if side == self.side and self.release_s is None:
                self.release_s = self.time_s  # the moment of the command: the start of this step
                self.released_state = self._lever_state()

    def _make_skill(self) -> LeverSkill:
        return LeverSkill(self.layout, self.side)

    def _shaping_potential(self) -> float:
        return PROGRESS_WEIGHT * float(np.clip(self._progress(), 0.0, 1.0))

    def _reward_terms(self, outcome_reward: float) -> dict[str, float]:
        progress = self._potential_change()
        timing = 0.0
        if self.outcome == "success" and self.reaction_s is not None:
            timing = TIMING_WEIGHT * max(0.0, 1.0 - self.reaction_s / self.success_window_s)
        return {"reward_outcome": float(outcome_reward), "reward_progress": float(progress), "reward_timing": float(timing)}

    def _task_spaces(self) -> dict:
        return {"grasp": spaces.MultiBinary(2)}

    def _task_obs(self) -> dict:
        return {"grasp": np.array([scenes.is_grasping(self.model, self.data, s) for s in names.ARM_SIDES], dtype=np.int8)}

    # -- evaluation ------------------------------------------------------------------------------
    def _evaluate(self) -> tuple[float, bool]:
        if self.target_onset_s is None:
            onset = next((e["time_s"] for e in self.step_events if self._is_target(e)), None)
            if onset is not None:
                self.target_onset_s = float(onset)
        if self.outcome != "running":
            return 0.0, True
        if self.release_s is not None:
            onset = self.target_onset_s
            self.false_release = onset is None or self.release_s < onset
            if onset is not None and self.release_s >= onset:
                self.reaction_s = self.release_s - onset
            self.outcome = self._judge_release()
        else:
            self.outcome = self._judge_running()
        if self.outcome == "running":
            return 0.0, False
        return (1.0 if self.outcome == "success" else -1.0), True

    def _judge_release(self) -> str:
        """The outcome of the release: ``early`` (before the target sound: a false release),
        the lever's fault (:meth:`_release_fault`), ``success`` or ``late``."""
        if self.false_release:
            return "early"
        fault = self._release_fault(self.released_state)
        if fault is not None:
            return fault
        return "success" if self.reaction_s <= self.success_window_s + 1e-9 else "late"

    def _judge_running(self) -> str:
        """The outcome while the hand holds: ``no_release`` once ``release_timeout_s`` have
        passed since the target sound, else ``running``."""
        if self.target_onset_s is not None and self.time_s - self.target_onset_s > self.release_timeout_s:
            return "no_release"
        return "running"

    def _task_info(self) -> dict:
        info = {
            "success": self.outcome == "success",
            "false_release": bool(self.false_release),
            "target_onset_s": None if self.target_onset_s is None else float(self.target_onset_s),
            "release_s": None if self.release_s is None else float(self.release_s),
            "reaction_s": None if self.reaction_s is None else float(self.reaction_s),
            "holding": bool(scenes.is_grasping(self.model, self.data, self.side)),
        }
        info.update(self._lever_state())
        return info


__all__ = ["CabinLeverTask"]
