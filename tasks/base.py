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

Sounds at arbitrary places: :meth:`HearingTaskEnv.schedule_sound` (the loop's soundscape,
:mod:`acoustic_sim.world.soundscape`); the world's own emitters sound through ``coupling.events``.

The parts live in their own modules, re-exported here: the action vector
(:mod:`tasks.actions`), the cabin's taught lever motions (:mod:`tasks.levers`), the shared
auditory models (:mod:`tasks.auditory`), the task sounds and ground truth
(:mod:`tasks.task_sounds`) and the specification docstrings' shared parts (:mod:`tasks.spec`).
"""

from __future__ import annotations

# MuJoCo picks its OpenGL backend when it is first imported: choose an offscreen one first.
from acoustic_sim.world.snapshot import HIDDEN_GEOM_GROUP, VIEWS, choose_gl_backend

choose_gl_backend()

import dataclasses
import math
from typing import ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE
from acoustic_sim.loop import HearingLoop, StepHearing
from acoustic_sim.world import names, scenes
from acoustic_sim.world.coupling import Coupling
from acoustic_sim.world.egonoise import MotorEgoNoise
from acoustic_sim.world.view import WorldView
from tasks import spec
from tasks.actions import ROBOT_JOINTS, ActionChannel, ActionLayout, action_layout
from tasks.auditory import PROFILES, TorchThreads, load_hrtf, make_pipeline
from tasks.levers import LEVERS, hold_lever, lever_arm_angles, lever_motion, settle
from tasks.skills import ACTION_MODES, Skill
from tasks.task_sounds import Soundscape, TaskSound, outside_placement

CLASSES: tuple[str, ...] = tuple(SOUND_CLASSES)
"""The six sound classes, in the order of the percept's probabilities."""

CONTROL_DT = 1.0 / FRAME_RATE
"""Seconds per environment step (16 ms)."""

BLOCK = math.ceil(SAMPLE_RATE / FRAME_RATE)
"""Samples of the ``audio`` observation (706): a 705-sample block is padded with one zero."""

N_BINS = 1025
"""Spectral bins per ear of the ``spectra`` observation."""

REWARD_MODES = ("sparse", "shaped")
"""The tasks' ``reward_mode`` values."""


# -- the base environment ----------------------------------------------------------------------------------


class HearingTaskEnv(gym.Env):
    """Base class of the hearing tasks (see the task classes for the specification).

    Subclasses set :attr:`scene_name`, :attr:`default_max_episode_s`, and implement
    :meth:`_scene_config`, :meth:`_setup_world`, :meth:`_schedule`, :meth:`_evaluate`
    (and optionally :meth:`_task_spaces`, :meth:`_task_obs`, :meth:`_task_info`). Their
    docstrings may use the placeholder lines of :mod:`tasks.spec` for the parts every task
    shares (the action and observation tables, the rewards, the common arguments), filled
    from :attr:`spec_action_rows`, :attr:`spec_action_notes`, :attr:`spec_observation_rows`
    and :attr:`spec_rewards`.

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
    spec_action_rows: ClassVar[tuple[tuple[str, str, str, str], ...]] = ()
    """The scene's action table rows after the robot's joints: (idx, channel, range, unit)."""
    spec_action_notes: ClassVar[str] = ""
    """What the scene's own action channels do (a sentence or two for the docstring)."""
    spec_observation_rows: ClassVar[tuple[tuple[str, str, str], ...]] = ()
    """The task's own observation table rows (key, shape, meaning), after proprioception."""
    spec_rewards: ClassVar[str] = ""
    """The docstring's Rewards section: what :meth:`_evaluate` gives."""
    spec_shaped_rewards: ClassVar[str] = ""
    """The shaped reward's terms (:meth:`_reward_terms`), for the Rewards section."""
    skill_rows: ClassVar[tuple[tuple[str, str, str, str], ...]] = ()
    """The ``skill`` action mode's table rows (idx, component, range, meaning): the skill's."""

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        cls.__doc__ = spec.expand(cls.__doc__, spec.parts(cls), owner=cls.__name__)

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, action_mode: str = "joints", reward_mode: str = "sparse",
                 audio_obs: bool = False, spectra_obs: bool = False, image_obs: bool = False,
                 image_size: tuple[int, int] = (120, 160), torch_threads: int | None = 1) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if profile not in PROFILES:
            raise ConfigError(f"profile must be one of {PROFILES}, got {profile!r}")
        if action_mode not in ACTION_MODES:
            raise ConfigError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")
        if reward_mode not in REWARD_MODES:
            raise ConfigError(f"reward_mode must be one of {REWARD_MODES}, got {reward_mode!r}")
        max_s = self.default_max_episode_s if max_episode_s is None else max_episode_s
        if not (isinstance(max_s, (int, float)) and np.isfinite(max_s) and max_s > 0):
            raise ConfigError(f"max_episode_s must be a positive number of seconds, got {max_episode_s!r}")
        h, w = image_size
        if not all(isinstance(v, int) and 16 <= v <= 480 for v in (h, w)) or w > 640:
            raise ConfigError(f"image_size must be (height, width) in pixels, 16-480 x 16-640, got {image_size!r}")
        if torch_threads is not None and (not isinstance(torch_threads, int) or torch_threads < 1):
            raise ConfigError(f"torch_threads must be None or a positive integer, got {torch_threads!r}")
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
        obs = {
            "joint_pos": spaces.Box(-np.pi, np.pi, shape=(len(ROBOT_JOINTS),), dtype=np.float32),
            "joint_vel": spaces.Box(-50.0, 50.0, shape=(len(ROBOT_JOINTS),), dtype=np.float32),
            "class_prob": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
            "class_dir": spaces.Box(-1.0, 1.0, shape=(3 * len(CLASSES),), dtype=np.float32),
            "class_conf": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
            "tracked_dir": spaces.Box(-1.0, 1.0, shape=(3 * len(CLASSES),), dtype=np.float32),
            "tracked_conf": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
            "tracked_decided": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
            "existence": spaces.Box(0.0, float(len(self.pipeline.ssdenet.bins)), shape=(self._n_directions,), dtype=np.float32),
        }
        obs.update(self._task_spaces())
        if self.audio_obs:
            obs["audio"] = spaces.Box(-1.0, 1.0, shape=(2, BLOCK), dtype=np.float32)
        if self.spectra_obs:
            obs["spectra"] = spaces.Box(0.0, float(N_BINS - 1) ** 2 * 4.0, shape=(2, N_BINS), dtype=np.float32)
        if self.image_obs:
            obs["image"] = spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8)
        self.observation_space = spaces.Dict(obs)
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
        self._scene_renderer = None
        self._eye_renderer = None

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
        view = WorldView(model, data)
        ego = MotorEgoNoise.from_view(view, sample_rate=self.ears.sample_rate)
        lo, hi = self.background_db_range
        self.background_db = float(task_rng.uniform(lo, hi)) if hi > lo else float(lo)
        room = dataclasses.replace(info.room, background_db_spl=self.background_db)
        from acoustic_sim.acoustics.renderer import BinauralRenderer

        renderer = BinauralRenderer(self.ears, room, rng=np.random.default_rng(render_ss), sample_rate=self.ears.sample_rate,
                                    background=True, late=True, ego_noise=ego)
        self.coupling = Coupling(model, data, renderer, rng=np.random.default_rng(events_ss),
                                 events_config=self._events_config())
        self.coupling.scene_info = info
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
        self._scene_renderer = None  # the model changed: renderers are rebuilt on demand
        self._eye_renderer = None
        return self._observation(), self._info([])

    def step(self, action):
        if self.coupling is None:
            raise ConfigError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        n = self.action_space.shape[0]
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise ConfigError(f"action must be {n} finite numbers in [-1, 1] ({self.action_mode} mode), got shape {a.shape}")
        a = np.clip(a, -1.0, 1.0)
        if self.skill is not None:
            a = self.skill.to_joints(a).astype(np.float64)
        for i, ch in enumerate(self.layout.channels):
            if ch.target.startswith("grasp:"):
                self._apply_special(ch, float(a[i]))
            else:
                self.data.ctrl[self._act_ids[ch.name]] = ch.from_unit(a[i])
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

    def at(self, t: float) -> float:
        """Project-clock time (s) of ``t`` seconds after the episode's start."""
        return self.start_s + float(t)

    # -- time ---------------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Time (s) at the end of the last step (the project clock)."""
        return self.coupling.time_s if self.coupling is not None else 0.0

    # -- sounds -------------------------------------------------------------------------------------
    def schedule_sound(self, name: str, label: str, signal, position, start_s: float, level_db: float, *,
                       frame: str = "room", outside: bool = False, kind: str = "distractor", detail: str = "") -> TaskSound:
        """Play a sound from a fixed point, ``start_s`` after the episode's start.

        The public way to add a distractor (or any sound) where the world has no emitter:
        a source of the renderer at ``position``, from its start sample on; the ground truth
        (``info["events"]``, ``info["sounding"]``) lists it as ``task/<name>``. See
        :meth:`acoustic_sim.world.soundscape.Soundscape.schedule_sound` for the details.

        Parameters
        ----------
        name : str
            Short name, unique in the episode.
        label : str
            The sound class (one of :data:`CLASSES`).
        signal : array_like, shape (n,), or callable
            Unit-RMS mono signal at 44100 Hz, or a zero-argument callable giving it when the sound
            starts (e.g. ``coupling.events.draw_later(emitter, label)``: drawn only if heard).
        position : array_like, shape (3,)
            Where it plays from (m): room frame (``frame="room"``, the acoustic room's, origin
            at a corner of the air volume; ``coupling.head_position`` is in it) or MuJoCo's
            world frame (``frame="world"``).
        start_s : float
            Start (s) after the episode's start (the first observation), not before the
            next step's block.
        level_db : float
            dB SPL at 1 m of the unit-RMS signal, -20..160 (``outside``: at 1 m outside).
        frame : {"room", "world"}
        outside : bool
            ``position`` is outside the acoustic room: the sound plays through the car body,
            from just inside the nearest wall (the coupling's law for the car horn).
        kind, detail : str
            The ground truth's event kind and free text.

        Returns
        -------
        TaskSound

        Raises
        ------
        ConfigError
            Before :meth:`reset`, or for a bad argument (see the soundscape's method).
        """
        if self.soundscape is None:
            raise ConfigError("call reset() before schedule_sound()")
        if not (isinstance(start_s, (int, float, np.floating, np.integer)) and np.isfinite(start_s)):
            raise ConfigError(f"schedule_sound({name!r}): start_s must be a finite time in s, got {start_s!r}")
        return self.hearing.schedule_sound(name, label, signal, position, self.at(start_s), level_db, frame=frame,
                                           outside=outside, kind=kind, detail=detail)

    @property
    def task_sounds(self) -> list[TaskSound]:
        """The task sounds of the episode, in the order they were scheduled."""
        return self.soundscape.sounds if self.soundscape is not None else []

    def sounding(self) -> list[dict]:
        """Ground truth: the sounds playing in the last block, each ``{source, label,
        direction (head frame unit vector), azimuth_deg, elevation_deg, start_s}``."""
        return self.soundscape.sounding()

    # -- observation and info ---------------------------------------------------------------------------
    def _observation(self) -> dict:
        v = self.view
        pos, vel = (a.astype(np.float32) for a in v.joint_states(self._joint_ids))
        probs = np.zeros(len(CLASSES), np.float32)
        dirs = np.zeros((len(CLASSES), 3), np.float32)
        conf = np.zeros(len(CLASSES), np.float32)
        existence = np.zeros(self._n_directions, np.float32)
        tdir = np.zeros((len(CLASSES), 3), np.float32)
        tconf = np.zeros(len(CLASSES), np.float32)
        tdec = np.zeros(len(CLASSES), np.float32)
        p = self.last_percept
        if p is not None:
            probs[:] = [p.probability(c) for c in CLASSES]
            best, best_p = None, -1.0
            for name, d in p.directions.items():
                i = CLASSES.index(name)
                dirs[i] = d.vector
                conf[i] = d.confidence
                if probs[i] > best_p:
                    best, best_p = d, probs[i]
            if best is not None:
                existence[:] = np.clip(best.existence, 0.0, self.observation_space["existence"].high[0])
            for name, t in p.tracked.items():
                if name in CLASSES:
                    i = CLASSES.index(name)
                    tdir[i], tconf[i], tdec[i] = t.head_vector, t.confidence, float(t.decided)
        obs = {
            "joint_pos": np.clip(pos, -np.pi, np.pi),
            "joint_vel": np.clip(vel, -50.0, 50.0),
            "class_prob": np.clip(probs, 0.0, 1.0),
            "class_dir": np.clip(dirs, -1.0, 1.0).reshape(-1),
            "class_conf": np.clip(conf, 0.0, 1.0),
            "tracked_dir": np.clip(tdir, -1.0, 1.0).reshape(-1),
            "tracked_conf": np.clip(tconf, 0.0, 1.0),
            "tracked_decided": tdec,
            "existence": existence,
        }
        obs.update(self._task_obs())
        if self.audio_obs:
            a = np.zeros((2, BLOCK), np.float32)
            if self.last_audio is not None:
                a[:, : self.last_audio.shape[1]] = self.last_audio
            obs["audio"] = a
        if self.spectra_obs:
            obs["spectra"] = self._last_spectra.copy()
        if self.image_obs:
            obs["image"] = self.eye_image()
        return obs

    def _info(self, new_events: list[dict]) -> dict:
        sounding = self.sounding()
        labels = np.zeros(len(CLASSES), np.int8)
        for snd in sounding:
            labels[CLASSES.index(snd["label"])] = 1
        info = {
            "time_s": self.time_s,
            "step": self.steps,
            "events": new_events,
            "sounding": sounding,
            "labels": labels,
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
        if self._scene_renderer is None:
            self._scene_renderer = _offscreen(self.model, 480, 640)
            cam = mujoco.MjvCamera()
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            view = VIEWS[self.scene_name]
            cam.lookat[:] = view.lookat
            cam.distance, cam.azimuth, cam.elevation = view.distance, view.azimuth, view.elevation
            opt = mujoco.MjvOption()
            opt.sitegroup[:] = 0
            opt.geomgroup[HIDDEN_GEOM_GROUP] = 0
            self._scene_camera, self._scene_option = cam, opt
        if self.scene_name == "room":  # follow the wheelchair, from far enough to see the person and the loudspeaker
            chair = self.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)[0]
            self._scene_camera.lookat[:] = (chair[0], chair[1], 0.8)
            self._scene_camera.distance, self._scene_camera.elevation = 6.0, -40.0
        self._scene_renderer.update_scene(self.data, self._scene_camera, scene_option=self._scene_option)
        return self._scene_renderer.render()

    def eye_image(self) -> np.ndarray:
        """What the right eye camera sees now: (height, width, 3) uint8."""
        h, w = self.image_size
        if self._eye_renderer is None:
            self._eye_renderer = _offscreen(self.model, h, w)
            opt = mujoco.MjvOption()
            opt.sitegroup[:] = 0
            self._eye_option = opt
        self._eye_renderer.update_scene(self.data, names.EYE_CAMERAS[1], scene_option=self._eye_option)
        return self._eye_renderer.render()

    def close(self) -> None:
        for r in (self._scene_renderer, self._eye_renderer):
            if r is not None:
                r.close()
        self._scene_renderer = self._eye_renderer = None
        super().close()


def _offscreen(model: mujoco.MjModel, height: int, width: int):
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # the GL backends raise RuntimeError, ImportError, OSError, ...
        raise ConfigError(
            f"offscreen rendering failed ({type(err).__name__}: {err}); install libegl1 or libosmesa6, "
            "or set MUJOCO_GL=egl or osmesa"
        ) from err


def db_at(level_db: float, distance_m: float) -> float:
    """Free-field level (dB SPL) at ``distance_m`` of a source of ``level_db`` at 1 m."""
    return float(level_db - 20.0 * math.log10(max(distance_m, 1e-3)))


__all__ = [
    "BLOCK",
    "CLASSES",
    "CONTROL_DT",
    "LEVERS",
    "N_BINS",
    "PROFILES",
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
