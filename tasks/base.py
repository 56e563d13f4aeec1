"""Shared machinery of the hearing tasks: the world, the ears and the auditory pipeline per step.

One environment step is one control step is one ear frame (16 ms, DESIGN.md section 1)::

    action (normalized joint targets, grasp, wheels)  ->  actuator targets (MjData.ctrl)
    HearingLoop.step()    acoustic_sim.loop: one StepHearing
      Coupling.advance()    8 physics steps of 2 ms, sound events, poses to the renderer
      Soundscape            the task's sounds placed anywhere (added to the renderer as they start)
      noise reference       ambient noise (measured at warm-up) + the motors' ego-noise now
      Coupling.render()     the block of eardrum pressure (2, 705 | 706) Pa
      Microphone            digital full scale, the ADC's 24 bits
      AuditoryPipeline      exactly one Percept for the ear frame that ends with the block
    _evaluate()           reward, termination, the task's outcome
    observation           proprioception + the percept (+ audio, spectra, eye image)

The env writes the controls and reads the :class:`~acoustic_sim.loop.StepHearing`; it calls
neither the renderer nor the pipeline itself, and :meth:`reset` lets the loop listen
(:meth:`~acoustic_sim.loop.HearingLoop.warm_up`) before the first observation.

The observation never holds ground truth; ``info`` does (true source directions, labels,
events, the task's outcome), for evaluation and for the ``oracle`` policy only.

Randomness comes only from ``self.np_random``: :meth:`HearingTaskEnv.reset` draws one
episode seed from it and spawns the generators of the renderer (noise, late tails), the
sound events (every sound drawn), the microphone (self-noise) and the task (placements,
distractor times) from that seed, so the same seed gives the same episode bit for bit.

Sounds at arbitrary places: :meth:`HearingTaskEnv.schedule_sound` (:mod:`tasks.episode_sounds`,
on the loop's soundscape, :mod:`acoustic_sim.world.soundscape`); the world's own emitters sound
through ``coupling.events``.

The parts live in their own modules, re-exported here: the action vector
(:mod:`tasks.actions`), the cabin's taught lever motions (:mod:`tasks.levers`), the shared
auditory models (:mod:`tasks.auditory`), the task sounds and ground truth
(:mod:`tasks.task_sounds`), the observation (:mod:`tasks.observations`), the common arguments
and the action check (:mod:`tasks.env_args`) and the pictures (:mod:`tasks.pictures`).
"""

from __future__ import annotations

# MuJoCo picks its OpenGL backend when it is first imported: choose an offscreen one first.
from acoustic_sim.world.snapshot import choose_gl_backend

choose_gl_backend()

import dataclasses
from typing import ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE
from acoustic_sim.loop import HearingLoop, StepHearing
from acoustic_sim.world import actuation, scenes
from acoustic_sim.world.coupling import Coupling
from tasks.actions import ROBOT_JOINTS, ActionChannel, ActionLayout, action_layout
from tasks.auditory import PROFILES, TorchThreads, load_hrtf, make_pipeline
from tasks.env_args import REWARD_MODES, check_arguments, joint_action
from tasks.episode_sounds import EpisodeSounds, db_at
from tasks.levers import LEVERS, hold_lever, lever_arm_angles, lever_motion, settle
from tasks.observations import (BLOCK, CLASSES, N_BINS, audio_observation, observation_space, percept_observation,
                                proprioception, sound_labels)
from tasks.pictures import Pictures
from tasks.skills import Skill
from tasks.task_sounds import Soundscape, TaskSound, outside_placement

CONTROL_DT = 1.0 / FRAME_RATE
"""Seconds per environment step (16 ms)."""


# -- the base environment ----------------------------------------------------------------------------------


class HearingTaskEnv(EpisodeSounds, gym.Env):
    """Base class of the hearing tasks (see the task classes for the specification).

    Subclasses set :attr:`scene_name`, :attr:`default_max_episode_s`, and implement
    :meth:`_scene_config`, :meth:`_setup_world`, :meth:`_schedule`, :meth:`_evaluate`
    (and optionally :meth:`_task_spaces`, :meth:`_task_obs`, :meth:`_task_info`). Their
    docstrings are their specifications, written out in full; the parts every task shares
    (the action and observation tables, the rewards, the common arguments) are the same
    text in each, which ``tests/test_tasks.py`` checks against ``tests/spec_docs.py``.

    Parameters (common to every task)
    ---------------------------------
    render_mode : str or None
        ``"rgb_array"``: :meth:`render` returns a 480 x 640 RGB picture of the scene.
    profile : str
        Auditory pipeline models: ``"paper"`` or ``"fast"`` (small networks, for tests).
    hrtf : str
        The ears (``"kemar"``, ``"spherical"`` or a SOFA path).
    max_episode_s : float or None
        Truncate after this much simulated time (s); default the task's.
    action_mode : str
        ``"joints"`` (the servo targets and the scene's extra channels) or ``"skill"`` (the
        task family's small space, :mod:`tasks.skills`: the zero action is harmless).
    reward_mode : str
        ``"sparse"`` (the outcome only) or ``"shaped"`` (the sum of the ``reward_*`` terms
        that ``info`` reports in both modes; :meth:`_reward_terms`).
    audio_obs, spectra_obs, image_obs : bool
        Add the raw audio block, the ear spectra, the right eye camera image.
    image_size : tuple of int
        (height, width) of the eye image and of the field of view check, pixels.
    torch_threads : int or None
        Torch threads while the pipeline runs (1: see :class:`~tasks.auditory.TorchThreads`);
        None leaves torch's setting.
    """

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": FRAME_RATE}
    scene_name = "cabin"
    default_max_episode_s = 10.0
    background_db_range = (40.0, 40.0)
    """Room background noise (dB SPL) drawn per episode."""
    coverage = 0.0
    """The auditory pipeline's attribution rule (``AuditoryPipeline(coverage=)``): 0, every
    frame counts for every detected class."""
    specificity = 0.0
    """The pipeline's second attribution rule (``AuditoryPipeline(specificity=)``): 0, off."""
    onset_windows = 1
    """Windows the pipeline takes at a rising onset (``AuditoryPipeline(onset_windows=)``): 1."""
    precedence = "wavefront"
    """The pipeline's evidence rule (``AuditoryPipeline(precedence=)``): the first wavefront at onsets."""
    fusion = "product"
    """How the pipeline fuses a frame's bins (``AuditoryPipeline(fusion=)``,
    :data:`acoustic_sim.auditory.ssdenet.FUSIONS`): ``"product"``, the default, or the
    paper's ``"sum"``."""
    timeout_reward = 0.0
    """The outcome reward when the episode reaches its limit (the cabin's: -1, a failure)."""
    warmup_s = 0.5
    """Seconds the ears listen before the episode starts, holding the start pose
    (:meth:`HearingLoop.warm_up <acoustic_sim.loop.HearingLoop.warm_up>`): the ears' history
    (the 0.4 s log-mel window) fills with the room's own sound, so the first observation does
    not carry the onset of the background noise (which the detector takes for a sound event),
    and the loop measures the ambient noise of the pipeline's noise reference."""

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, action_mode: str = "joints", reward_mode: str = "sparse",
                 audio_obs: bool = False, spectra_obs: bool = False, image_obs: bool = False,
                 image_size: tuple[int, int] = (120, 160), torch_threads: int | None = 1) -> None:
        max_s, (h, w) = check_arguments(render_mode=render_mode, render_modes=self.metadata["render_modes"],
                                        profile=profile, action_mode=action_mode, reward_mode=reward_mode,
                                        max_episode_s=max_episode_s, default_max_episode_s=self.default_max_episode_s,
                                        image_size=image_size, torch_threads=torch_threads)
        self.render_mode = render_mode
        self.profile = profile
        self.hrtf_name = hrtf
        self.max_episode_s = float(max_s)
        self.max_episode_steps = round(self.max_episode_s * FRAME_RATE)
        self.audio_obs, self.spectra_obs, self.image_obs = bool(audio_obs), bool(spectra_obs), bool(image_obs)
        self.image_size = (h, w)
        self._threads = TorchThreads(torch_threads)
        self.layout = action_layout(self.scene_name)
        self.action_mode, self.reward_mode = action_mode, reward_mode
        self.skill = self._make_skill() if action_mode == "skill" else None
        self.pipeline = make_pipeline(profile, hrtf, self.coverage, self.specificity, self.onset_windows, self.fusion,
                                      self.precedence)
        self.ears = load_hrtf(hrtf)
        self._n_directions = len(self.pipeline.grid)
        self.action_space = (self.skill.space if self.skill is not None
                             else spaces.Box(-1.0, 1.0, shape=(len(self.layout),), dtype=np.float32))
        self.observation_space = observation_space(
            n_directions=self._n_directions, existence_high=float(len(self.pipeline.ssdenet.bins)),
            task_spaces=self._task_spaces(), audio=self.audio_obs, spectra=self.spectra_obs,
            image_size=(h, w) if self.image_obs else None)
        self.coupling: Coupling | None = None
        self.hearing: HearingLoop | None = None
        """The episode's hearing loop (the control step's chain from the world to the percept)."""
        self.last_hearing: StepHearing | None = None
        """What the last step heard (None before the first)."""
        self.last_percept = None
        """The Percept of the last step (None before the first)."""
        self.last_audio: np.ndarray | None = None
        """The digital ear block (2, 705 | 706) of the last step."""
        self.step_callback = None
        """Optional ``f(env, obs, reward, terminated, truncated, info)`` called at the end of
        every step (the runner's hook for recorders)."""
        self.soundscape: Soundscape | None = None
        """The episode's task sounds and ground truth (see :meth:`schedule_sound`)."""
        self._pictures = Pictures()

    # -- hooks ------------------------------------------------------------------------------------
    def _task_spaces(self) -> dict:
        return {}

    def _draw_hidden(self, rng: np.random.Generator) -> dict:
        """Draw the episode's hidden parameters (kept out of the observation; reported in
        ``info``), from their own stream."""
        return {}

    def _events_config(self):
        """The :class:`~acoustic_sim.world.events.EventsConfig` of the episode (None: the defaults)."""
        return None

    def _scene_config(self, rng: np.random.Generator):
        raise NotImplementedError

    def _setup_world(self, model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator) -> None:
        """Put the world in the episode's initial state (before the coupling is built)."""

    def _schedule(self, rng: np.random.Generator) -> None:
        """Schedule the episode's requests and task sounds (after the coupling is built)."""

    def _evaluate(self) -> tuple[float, bool]:
        """Reward and termination after a step; set :attr:`outcome`."""
        raise NotImplementedError

    def _task_obs(self) -> dict:
        return {}

    def _task_info(self) -> dict:
        return {}

    def _apply_special(self, channel: ActionChannel, value: float) -> None:
        """Channels that are not actuators (the grasp commands)."""
        raise ConfigError(f"unhandled action channel {channel.name!r}")

    def _make_skill(self) -> Skill:
        """The ``skill`` action mode's mapping (:mod:`tasks.skills`)."""
        raise ConfigError(f"{type(self).__name__} has no skill action mode")

    def _reward_terms(self, outcome_reward: float) -> dict[str, float]:
        """This step's reward terms (``info``'s ``reward_*``); the shaped reward is their sum,
        the sparse one ``outcome_reward``. Tasks add shaping terms to ``reward_outcome``."""
        return {"reward_outcome": float(outcome_reward)}

    def _shaping_potential(self) -> float:
        """The shaped reward's potential in the current state (ground truth; 0: none)."""
        return 0.0

    def _potential_change(self) -> float:
        """The change of :meth:`_shaping_potential` since the last step (or the episode's
        start): a potential-based term, which sums over an episode to its end value minus
        its start value."""
        potential = self._shaping_potential()
        change, self._potential = potential - self._potential, potential
        return change

    # -- episode ------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        ss = np.random.SeedSequence(int(self.np_random.integers(2**63)))
        # A fifth stream for the hidden per-episode parameters: spawning it leaves the first
        # four (and so every episode without hidden variation) as they were.
        render_ss, events_ss, mic_ss, task_ss, hidden_ss = ss.spawn(5)
        task_rng = np.random.default_rng(task_ss)
        self.hidden = self._draw_hidden(np.random.default_rng(hidden_ss))
        config = self._scene_config(task_rng)
        model, data, info = scenes.load_scene(self.scene_name, config=config)
        self._setup_world(model, data, task_rng)
        lo, hi = self.background_db_range
        self.background_db = float(task_rng.uniform(lo, hi)) if hi > lo else float(lo)
        room = dataclasses.replace(info.room, background_db_spl=self.background_db)
        self.coupling = Coupling.wired(model, data, info, ears=self.ears, render_rng=np.random.default_rng(render_ss),
                                       events_rng=np.random.default_rng(events_ss), room=room,
                                       events_config=self._events_config())
        self.model, self.data, self.view = model, data, self.coupling.view
        self.microphone = Microphone(rng=np.random.default_rng(mic_ss), sample_rate=self.ears.sample_rate)
        self.hearing = HearingLoop(self.coupling, self.microphone, self.pipeline, soundscape=Soundscape(self.coupling),
                                   threads=self._threads)  # resets the pipeline
        self._act_ids = {c.name: model.actuator(c.target).id for c in self.layout.channels if not c.target.startswith("grasp:")}
        self._joint_ids = list(ROBOT_JOINTS)
        self.soundscape = self.hearing.soundscape
        self.events_log: list[dict] = []
        self.steps = 0
        self.step_events: list[dict] = []
        self.outcome = "running"
        self.last_hearing = None
        self.last_audio = None
        self._last_spectra = np.zeros((2, N_BINS), np.float32)
        warm = self.hearing.warm_up(self.warmup_s)  # the ears listen, holding the start pose (see warmup_s)
        self.last_percept = warm.percept if warm is not None else None
        self.start_s = self.coupling.time_s
        self._schedule(task_rng)
        if self.skill is not None:
            self.skill.reset(self)
        self._reward_terms_last: dict[str, float] = {}
        self._potential = self._shaping_potential()
        self._pictures = Pictures()  # the model changed: renderers are rebuilt on demand
        return self._observation(), self._info([])

    def step(self, action):
        if self.coupling is None:
            raise ConfigError("call reset() before step()")
        a = joint_action(action, self.action_space.shape[0], self.action_mode, self.skill)
        for i, ch in enumerate(self.layout.channels):
            if ch.target.startswith("grasp:"):
                self._apply_special(ch, float(a[i]))
            else:
                actuation.set_control(self.model, self.data, self._act_ids[ch.name], ch.from_unit(a[i]))
        heard = self.last_hearing = self.hearing.step()
        new = list(heard.events)
        self.step_events = new  # events that started in this step's block: world events and task sounds
        self.last_audio = heard.audio
        self.last_percept = heard.percept
        self.steps += 1
        if self.spectra_obs:
            self._last_spectra = heard.frame_power().astype(np.float32)
        reward, terminated = self._evaluate()
        truncated = not terminated and self.steps >= self.max_episode_steps
        if truncated and self.outcome == "running":
            self.outcome = "timeout"
            reward = self.timeout_reward
        terms = self._reward_terms_last = self._reward_terms(reward)
        if self.reward_mode == "shaped":
            reward = float(sum(terms.values()))
        obs, info = self._observation(), self._info(new)
        if self.step_callback is not None:
            self.step_callback(self, obs, reward, terminated, truncated, info)
        return obs, float(reward), bool(terminated), bool(truncated), info

    # -- observation and info ---------------------------------------------------------------------------
    def _observation(self) -> dict:
        pos, vel = (a.astype(np.float32) for a in self.view.joint_states(self._joint_ids))
        obs = proprioception(pos, vel)
        obs.update(percept_observation(self.last_percept, self._n_directions, self.observation_space["existence"].high[0]))
        obs.update(self._task_obs())
        if self.audio_obs:
            obs["audio"] = audio_observation(self.last_audio)
        if self.spectra_obs:
            obs["spectra"] = self._last_spectra.copy()
        if self.image_obs:
            obs["image"] = self.eye_image()
        return obs

    def _info(self, new_events: list[dict]) -> dict:
        sounding = self.sounding()
        info = {
            "time_s": self.time_s,
            "step": self.steps,
            "events": new_events,
            "sounding": sounding,
            "labels": sound_labels(sounding),
            "outcome": self.outcome,
            "hidden": dict(self.hidden),
        }
        info.update(self._reward_terms_last)
        info.update(self._task_info())
        return info

    # -- pictures -----------------------------------------------------------------------------------------
    def render(self):
        """A 480 x 640 RGB picture of the scene from its fixed camera (``render_mode="rgb_array"``)."""
        if self.render_mode != "rgb_array" or self.coupling is None:
            return None
        return self._pictures.scene(self.model, self.data, self.scene_name, self.view)

    def eye_image(self) -> np.ndarray:
        """What the right eye camera sees now: (height, width, 3) uint8."""
        return self._pictures.eye(self.model, self.data, self.image_size)

    def close(self) -> None:
        self._pictures.close()
        super().close()


__all__ = [
    "BLOCK",
    "CLASSES",
    "CONTROL_DT",
    "LEVERS",
    "N_BINS",
    "PROFILES",
    "REWARD_MODES",
    "ROBOT_JOINTS",
    "ActionChannel",
    "ActionLayout",
    "HearingTaskEnv",
    "TaskSound",
    "action_layout",
    "db_at",
    "hold_lever",
    "lever_arm_angles",
    "lever_motion",
    "make_pipeline",
    "outside_placement",
    "settle",
]
