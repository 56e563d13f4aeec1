"""Shared machinery of the hearing tasks: the world, the ears and the auditory pipeline per step.

One environment step is one control step is one ear frame (16 ms, DESIGN.md section 1)::

    action (normalized joint targets, grasp, wheels)  ->  actuator targets (MjData.ctrl)
    Coupling.advance()    8 physics steps of 2 ms, sound events, poses to the renderer
    task sounds           distractors placed anywhere (added to the renderer when they start)
    Coupling.render()     the block of eardrum pressure (2, 705 | 706) Pa
    Microphone            digital full scale, the ADC's 24 bits
    AuditoryPipeline      exactly one Percept for the ear frame that ends with the block
    observation           proprioception + the percept (+ audio, spectra, eye image)

The observation never holds ground truth; ``info`` does (true source directions, labels,
events, the task's outcome), for evaluation and for the ``oracle`` policy only.

Randomness comes only from ``self.np_random``: :meth:`HearingTaskEnv.reset` draws one
episode seed from it and spawns the generators of the renderer (noise, late tails), the
sound events (every sound drawn), the microphone (self-noise) and the task (placements,
distractor times) from that seed, so the same seed gives the same episode bit for bit.

Sounds at arbitrary places. The world's emitters (:data:`acoustic_sim.world.events.EMITTERS`)
sound from fixed sites. A task's distractors that come from anywhere else (another car's
reverse alarm behind, a turn-signal relay, a radio) are :class:`TaskSound` s: a source of the
coupling's renderer at a fixed room point, added in the block in which it starts and removed
once it and its reverberation are over. A sound outside the acoustic room (another vehicle)
plays, as the coupling plays the car horn, from the nearest point just inside the wall at
its level minus the car body's transmission loss and the spreading to that point.
"""

from __future__ import annotations

# MuJoCo picks its OpenGL backend when it is first imported: choose an offscreen one first.
from acoustic_sim.world.snapshot import HIDDEN_GEOM_GROUP, VIEWS, choose_gl_backend

choose_gl_backend()

import dataclasses
import functools
import math
from typing import ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from acoustic_sim.acoustics.microphone import FULL_SCALE_PA, Microphone
from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE, db_spl_to_pa, frame_end_sample, vec_to_sph
from acoustic_sim.world import names, scene
from acoustic_sim.world.coupling import Coupling
from acoustic_sim.world.egonoise import MotorEgoNoise
from acoustic_sim.world.events import SoundEvent
from acoustic_sim.world.view import WorldView

CLASSES: tuple[str, ...] = tuple(SOUND_CLASSES)
"""The six sound classes, in the order of the percept's probabilities."""

CONTROL_DT = 1.0 / FRAME_RATE
"""Seconds per environment step (16 ms)."""

BLOCK = math.ceil(SAMPLE_RATE / FRAME_RATE)
"""Samples of the ``audio`` observation (706): a 705-sample block is padded with one zero."""

N_BINS = 1025
"""Spectral bins per ear of the ``spectra`` observation."""

ROBOT_JOINTS: tuple[str, ...] = (*names.NECK_JOINTS, *names.EYE_JOINTS, *names.arm_joints("left"), *names.arm_joints("right"))
"""Joints of the proprioception, in this order: neck yaw, pitch; eye yaw, pitch; left arm
shoulder pitch, roll, yaw, elbow, wrist; the same for the right arm."""

PROFILES = ("paper", "fast")
"""Auditory pipeline profiles an env accepts."""


# -- actions ----------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ActionChannel:
    """One entry of the action vector.

    Attributes
    ----------
    name : str
        Short name (``neck_yaw``, ``left_elbow``, ``grasp_left``, ``left_wheel``).
    target : str
        Full actuator name, or ``grasp:<side>`` for a hand's grasp command.
    low, high : float
        What -1 and +1 mean (rad for joints, rad/s for wheels; grasp: -1 open, +1 hold).
    unit : str
    """

    name: str
    target: str
    low: float
    high: float
    unit: str

    def to_unit(self, value: float) -> float:
        """Physical value -> normalized action in [-1, 1] (clipped)."""
        return float(np.clip(2.0 * (value - self.low) / (self.high - self.low) - 1.0, -1.0, 1.0))

    def from_unit(self, a: float) -> float:
        """Normalized action -> physical value."""
        return self.low + (float(a) + 1.0) * 0.5 * (self.high - self.low)


class ActionLayout:
    """The action vector of a scene: channel order, ranges, and the robot's rest pose.

    Parameters
    ----------
    channels : sequence of ActionChannel
    home : dict of str to float
        Rest value of each channel (rad, rad/s, grasp +-1).
    """

    def __init__(self, channels, home: dict[str, float]) -> None:
        self.channels: tuple[ActionChannel, ...] = tuple(channels)
        self.names: tuple[str, ...] = tuple(c.name for c in self.channels)
        self._index = {c.name: i for i, c in enumerate(self.channels)}
        self.home_values = dict(home)
        self._home = np.array([self._unit(c, home[c.name]) for c in self.channels], dtype=np.float32)

    def __len__(self) -> int:
        return len(self.channels)

    @staticmethod
    def _unit(channel: ActionChannel, value: float) -> float:
        return float(np.clip(value, -1.0, 1.0)) if channel.target.startswith("grasp:") else channel.to_unit(value)

    def index(self, name: str) -> int:
        """Position of channel ``name`` in the action vector."""
        if name not in self._index:
            raise ConfigError(f"no action channel {name!r}; channels: {', '.join(self.names)}")
        return self._index[name]

    def home(self) -> np.ndarray:
        """The normalized action of the rest pose (float32; grasp commands open, wheels still)."""
        return self._home.copy()

    def action(self, values: dict[str, float], base=None) -> np.ndarray:
        """A normalized action (float32) from physical values by channel name (rad, rad/s,
        grasp +-1); channels not given keep ``base`` (default: the rest pose)."""
        a = self.home() if base is None else np.array(base, dtype=np.float32)
        for name, v in values.items():
            i = self.index(name)
            a[i] = self._unit(self.channels[i], v)
        return a

    def arm(self, side: str, angles) -> dict[str, float]:
        """``{channel: angle}`` for the five joints of one arm (rad), shoulder to wrist."""
        return {f"{side}_{s}": float(q) for s, q in zip(names.ARM_JOINT_SUFFIXES, angles)}


def _short(joint: str) -> str:
    return joint[len(names.ROBOT):]


@functools.cache
def action_layout(scene_name: str) -> ActionLayout:
    """The action layout of ``cabin`` (joints + two grasp commands) or ``room`` (joints +
    two wheel speeds); ranges are the actuators' control ranges, the rest pose the robot's
    ``home`` keyframe (read from a freshly loaded scene)."""
    model, data, _ = scene.load_scene(scene_name)
    channels, home = [], {}
    for joint in ROBOT_JOINTS:
        act = model.actuator(joint)
        lo, hi = (float(v) for v in act.ctrlrange)
        channels.append(ActionChannel(_short(joint), joint, lo, hi, "rad"))
        home[_short(joint)] = float(data.actuator(joint).ctrl[0])
    if scene_name == "cabin":
        for side in names.ARM_SIDES:
            channels.append(ActionChannel(f"grasp_{side}", f"grasp:{side}", -1.0, 1.0, "1"))
            home[f"grasp_{side}"] = -1.0
    else:
        for wheel in names.WHEEL_JOINTS:
            act = model.actuator(wheel)
            lo, hi = (float(v) for v in act.ctrlrange)
            short = wheel[len(names.WHEELCHAIR):]
            channels.append(ActionChannel(short, wheel, lo, hi, "rad/s"))
            home[short] = 0.0
    return ActionLayout(channels, home)


# -- taught lever motions ------------------------------------------------------------------------------

LEVERS = {"left": (names.GEARSHIFT_JOINT, names.GEARSHIFT_KNOB_SITE), "right": (names.BRAKE_JOINT, names.BRAKE_HANDLE_SITE)}
"""Each hand's lever in the cabin: (hinge joint, handle site)."""


@functools.cache
def lever_motion(side: str, step_deg: float = 0.5, max_deg: float = 50.0) -> tuple[np.ndarray, np.ndarray]:
    """A taught motion: arm joint angles that move a hand's lever along its arc.

    The robot's knowledge of its own arm and of the cabin's layout (as the paper's robot was
    taught its motions): for lever angles 0, ``step_deg``, ... ``max_deg`` (deg from the rest
    angle of the scene's initial state, the gearshift in P and the brake down), the angles of
    the five arm joints that put the palm where it holds the handle, by position inverse
    kinematics (:func:`acoustic_sim.world.scene.reach`) on a freshly loaded cabin, each
    solution warm-started from the previous one. Angles the arm cannot reach end the table.

    Returns
    -------
    lever_deg : numpy.ndarray, shape (K,)
    arm : numpy.ndarray, shape (K, 5)
        rad, shoulder pitch, roll, yaw, elbow, wrist.
    """
    if side not in LEVERS:
        raise ConfigError(f"side must be 'left' (gearshift) or 'right' (brake), got {side!r}")
    model, data, _ = scene.load_scene("cabin")
    joint, site = LEVERS[side]
    jid = model.joint(joint).id
    axis, anchor = data.xaxis[jid].copy(), data.xanchor[jid].copy()
    handle = data.site(site).xpos.copy()
    qadr = [model.joint(j).qposadr[0] for j in names.arm_joints(side)]
    angles, rows = [], []
    for deg in np.arange(0.0, max_deg + 1e-9, step_deg):
        r = _rotation(axis, np.deg2rad(deg))
        target = anchor + r @ (handle - anchor)
        try:
            q = scene.reach(model, data, side, target, max_error=0.01)
        except ConfigError:
            break
        data.qpos[qadr] = q  # warm start for the next angle
        angles.append(deg)
        rows.append(q)
    return np.asarray(angles), np.asarray(rows)


def lever_arm_angles(side: str, lever_deg: float) -> np.ndarray:
    """Arm joint angles (rad, (5,)) of the taught motion at lever angle ``lever_deg``
    (interpolated, clamped to the reachable part of the arc)."""
    deg, arm = lever_motion(side)
    return np.array([np.interp(lever_deg, deg, arm[:, j]) for j in range(arm.shape[1])])


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


# -- the auditory pipeline, shared models ---------------------------------------------------------------


@functools.cache
def _hrtf(name: str):
    from acoustic_sim.acoustics.hrtf import HRTF

    return HRTF.load(name)


@functools.cache
def _models(hrtf_name: str, profile: str):
    """Trained models of a profile, loaded (or trained and cached) once per process; their
    weights are only read, so every env of the process shares them."""
    from acoustic_sim.auditory.melcnn import MelCNN
    from acoustic_sim.auditory.ssdenet import SSDENetBank
    from acoustic_sim.directions import DirectionGrid

    ears = _hrtf(hrtf_name)
    grid = DirectionGrid.paper(ears)
    bank = SSDENetBank.load_or_train(ears, grid, profile, progress=True)
    cnn = MelCNN.load_or_train(profile, progress=True)
    return ears, grid, bank, cnn


@functools.cache
def _microphone_noise_power() -> np.ndarray:
    from acoustic_sim.auditory.pipeline import microphone_noise_power

    return microphone_noise_power()


def make_pipeline(profile: str = "paper", hrtf: str = "kemar"):
    """A fresh :class:`~acoustic_sim.auditory.pipeline.AuditoryPipeline` (its own streaming
    state) over the process's shared models of ``profile``."""
    from acoustic_sim.auditory.pipeline import AuditoryPipeline

    if profile not in PROFILES:
        raise ConfigError(f"unknown pipeline profile {profile!r}; valid: {', '.join(PROFILES)}")
    ears, grid, bank, cnn = _models(hrtf, profile)
    return AuditoryPipeline(hrtf=ears, grid=grid, ssdenet=bank, melcnn=cnn, noise_power=_microphone_noise_power())


class _TorchThreads:
    """Run a block with at most ``n`` torch threads (restored after).

    The pipeline's networks are small: per frame, torch's OpenMP workers and the renderer's
    OpenBLAS workers busy-wait against each other on a 2-core machine (measured: 50 ms per
    frame instead of 1.5 ms); one torch thread avoids it.
    """

    def __init__(self, n: int | None) -> None:
        self.n = n

    def __enter__(self):
        if self.n is not None:
            import torch

            self._old = torch.get_num_threads()
            if self._old != self.n:
                torch.set_num_threads(self.n)
        return self

    def __exit__(self, *exc) -> None:
        if self.n is not None and self._old != self.n:
            import torch

            torch.set_num_threads(self._old)


# -- sounds placed by the task ---------------------------------------------------------------------------


@dataclasses.dataclass
class TaskSound:
    """A sound the task plays from a fixed point of the acoustic room.

    Attributes
    ----------
    name : str
        Renderer source name (``task/<what>``); unique per episode.
    label : str
        Its sound class (one of :data:`CLASSES`): what a classifier should say.
    kind : str
        What it is, for the ground truth (``distractor``).
    detail : str
        Free text (``beeper behind``, ``turn signal``, ``radio``).
    signal : numpy.ndarray
        Unit-RMS mono signal at the project rate.
    position : numpy.ndarray, shape (3,)
        Room frame (m): where it plays from (inside the room).
    level_db : float
        dB SPL at 1 m from ``position`` of the unit-RMS signal.
    start : int
        Start sample on the project clock.
    """

    name: str
    label: str
    kind: str
    detail: str
    signal: np.ndarray
    position: np.ndarray
    level_db: float
    start: int
    added: bool = False
    removed: bool = False

    @property
    def end(self) -> int:
        return self.start + int(self.signal.size)


def outside_placement(coupling: Coupling, point_room, level_db: float, margin: float = 0.1) -> tuple[np.ndarray, float]:
    """Where and how loud a source outside the acoustic room plays inside it.

    The coupling's law for the car horn (:mod:`acoustic_sim.world.coupling`): from the point
    ``margin`` (m) inside the walls nearest to ``point_room`` (room frame, m), at
    ``level_db`` (dB SPL at 1 m outside) minus the body's transmission loss and minus the
    spreading ``20 log10(max(d, 1 m))`` from the source to that point.
    """
    p = np.asarray(point_room, dtype=float)
    inside = coupling.frame.nearest_inside(p, margin)
    d = float(np.linalg.norm(p - inside))
    return inside, level_db - coupling.events.config.transmission_loss_db - 20.0 * math.log10(max(d, 1.0))


# -- the base environment ----------------------------------------------------------------------------------


class HearingTaskEnv(gym.Env):
    """Base class of the hearing tasks (see the task classes for the specification).

    Subclasses set :attr:`scene_name`, :attr:`default_max_episode_s`, and implement
    :meth:`_scene_config`, :meth:`_setup_world`, :meth:`_schedule`, :meth:`_evaluate`
    (and optionally :meth:`_task_spaces`, :meth:`_task_obs`, :meth:`_task_info`).

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
    audio_obs, spectra_obs, image_obs : bool
        Add the raw audio block, the ear spectra, the right eye camera image.
    image_size : tuple of int
        (height, width) of the eye image and of the field of view check, pixels.
    torch_threads : int or None
        Torch threads while the pipeline runs (1: see :class:`_TorchThreads`); None
        leaves torch's setting.
    """

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"], "render_fps": FRAME_RATE}
    scene_name = "cabin"
    default_max_episode_s = 10.0
    background_db_range = (40.0, 40.0)
    """Room background noise (dB SPL) drawn per episode."""
    warmup_s = 0.5
    """Seconds the ears listen before the episode starts (see :meth:`_warm_up`)."""

    def __init__(self, *, render_mode: str | None = None, profile: str = "paper", hrtf: str = "kemar",
                 max_episode_s: float | None = None, audio_obs: bool = False, spectra_obs: bool = False,
                 image_obs: bool = False, image_size: tuple[int, int] = (120, 160), torch_threads: int | None = 1) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if profile not in PROFILES:
            raise ConfigError(f"profile must be one of {PROFILES}, got {profile!r}")
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
        self._threads = _TorchThreads(torch_threads)
        self.layout = action_layout(self.scene_name)
        self.pipeline = make_pipeline(profile, hrtf)
        self.ears = _hrtf(hrtf)
        self._n_directions = len(self.pipeline.grid)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(len(self.layout),), dtype=np.float32)
        obs = {
            "joint_pos": spaces.Box(-np.pi, np.pi, shape=(len(ROBOT_JOINTS),), dtype=np.float32),
            "joint_vel": spaces.Box(-50.0, 50.0, shape=(len(ROBOT_JOINTS),), dtype=np.float32),
            "class_prob": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
            "class_dir": spaces.Box(-1.0, 1.0, shape=(len(CLASSES), 3), dtype=np.float32),
            "class_conf": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
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
        self.last_percept = None
        """The Percept of the last step (None before the first)."""
        self.last_audio: np.ndarray | None = None
        """The digital ear block (2, 705 | 706) of the last step."""
        self.step_callback = None
        """Optional ``f(env, obs, reward, terminated, truncated, info)`` called at the end of
        every step (the runner's hook for recorders)."""
        self._scene_renderer = None
        self._eye_renderer = None

    # -- hooks ------------------------------------------------------------------------------------
    def _task_spaces(self) -> dict:
        return {}

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

    # -- episode ------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        ss = np.random.SeedSequence(int(self.np_random.integers(2**63)))
        render_ss, events_ss, mic_ss, task_ss = ss.spawn(4)
        task_rng = np.random.default_rng(task_ss)
        config = self._scene_config(task_rng)
        model, data, info = scene.load_scene(self.scene_name, config=config)
        self._setup_world(model, data, task_rng)
        view = WorldView(model, data)
        ego = MotorEgoNoise.from_view(view, sample_rate=self.ears.sample_rate)
        lo, hi = self.background_db_range
        self.background_db = float(task_rng.uniform(lo, hi)) if hi > lo else float(lo)
        room = dataclasses.replace(info.room, background_db_spl=self.background_db)
        from acoustic_sim.acoustics.renderer import BinauralRenderer

        renderer = BinauralRenderer(self.ears, room, rng=np.random.default_rng(render_ss), sample_rate=self.ears.sample_rate,
                                    background=True, late=True, ego_noise=ego)
        self.coupling = Coupling(model, data, renderer, rng=np.random.default_rng(events_ss))
        self.coupling.scene_info = info
        self.model, self.data, self.view = model, data, self.coupling.view
        self.microphone = Microphone(rng=np.random.default_rng(mic_ss), sample_rate=self.ears.sample_rate)
        self.pipeline.reset()
        self._act_ids = {c.name: model.actuator(c.target).id for c in self.layout.channels if not c.target.startswith("grasp:")}
        self._joint_ids = list(ROBOT_JOINTS)
        self.task_sounds: list[TaskSound] = []
        self.events_log: list[dict] = []
        self._active: list[dict] = []  # ground truth: sounds playing (world events and task sounds)
        self.steps = 0
        self.step_events: list[dict] = []
        self.outcome = "running"
        self.last_percept = None
        self.last_audio = None
        self._last_spectra = np.zeros((2, N_BINS), np.float32)
        self._warm_up()
        self.start_s = self.coupling.time_s
        self._schedule(task_rng)
        self._scene_renderer = None  # the model changed: renderers are rebuilt on demand
        self._eye_renderer = None
        return self._observation(), self._info([])

    def step(self, action):
        if self.coupling is None:
            raise ConfigError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (len(self.layout),) or not np.all(np.isfinite(a)):
            raise ConfigError(f"action must be {len(self.layout)} finite numbers in [-1, 1], got shape {a.shape}")
        a = np.clip(a, -1.0, 1.0)
        for i, ch in enumerate(self.layout.channels):
            if ch.target.startswith("grasp:"):
                self._apply_special(ch, float(a[i]))
            else:
                self.data.ctrl[self._act_ids[ch.name]] = ch.from_unit(a[i])
        c = self.coupling
        events = c.advance()
        new = self._track_world_events(events)
        new += self._start_task_sounds()
        self.step_events = new  # events that started in this step's block: world events and task sounds
        self._set_noise_reference()
        pressure = c.render()
        self.last_audio = self.microphone(pressure)
        with self._threads:
            percepts = self.pipeline.process(self.last_audio)
        if len(percepts) != 1:
            raise ConfigError(f"the pipeline returned {len(percepts)} percepts for one control block (expected exactly 1)")
        self.last_percept = percepts[0]
        self.steps += 1
        if self.spectra_obs:
            self._last_spectra = self._frame_power().astype(np.float32)
        reward, terminated = self._evaluate()
        truncated = not terminated and self.steps >= self.max_episode_steps
        if truncated and self.outcome == "running":
            self.outcome = "timeout"
        self._end_task_sounds()
        obs, info = self._observation(), self._info(new)
        if self.step_callback is not None:
            self.step_callback(self, obs, reward, terminated, truncated, info)
        return obs, float(reward), bool(terminated), bool(truncated), info

    def _warm_up(self) -> None:
        """Listen for :attr:`warmup_s` before the episode starts, holding the start pose: the
        ears' history (the 0.4 s log-mel window) fills with the room's own sound, so the first
        observation does not carry the onset of the background noise (which the detector
        takes for a sound event)."""
        c = self.coupling
        n = round(self.warmup_s * FRAME_RATE)
        ambient, counted = np.zeros((2, N_BINS)), 0
        self.ambient_power = _microphone_noise_power()
        for k in range(n):
            c.advance()
            self._start_task_sounds()
            self._set_noise_reference()
            with self._threads:
                percepts = self.pipeline.process(self.microphone(c.render()))
            self.last_percept = percepts[-1] if percepts else self.last_percept
            if k >= n // 3:  # frames whose 2048 samples are all audio (the first are partly zeros)
                ambient += self._frame_power()
                counted += 1
        if counted:
            self.ambient_power = np.maximum(ambient / counted, _microphone_noise_power())
        self._active.clear()

    def _frame_power(self) -> np.ndarray:
        """|X|^2 (2, 1025) of the ear frame the pipeline analysed last (full-scale units)."""
        fe = self.pipeline.frontend
        return np.abs(np.fft.rfft(fe.buffer[:, -fe.n_fft:] * fe.window, axis=-1)) ** 2

    def _set_noise_reference(self) -> None:
        """The pipeline's noise reference: the ambient noise measured while still (room
        background and microphone, :meth:`_warm_up`) plus the motors' expected ego-noise at
        this block's level. The paper records the robot's driving noise in advance, in the
        room, so its reference holds the room's steady noise too: a bin counts only where a
        sound stands 10 times above both."""
        c = self.coupling
        ego = c.ego_noise.expected_power_spectrum(window=self.pipeline.frontend.window) if c.ego_noise is not None else 0.0
        self.pipeline.set_noise_power(self.ambient_power + np.asarray(ego) / FULL_SCALE_PA**2)

    def at(self, t: float) -> float:
        """Project-clock time (s) of ``t`` seconds after the episode's start."""
        return self.start_s + float(t)

    # -- time ---------------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Time (s) at the end of the last step (the project clock)."""
        return self.coupling.time_s if self.coupling is not None else 0.0

    # -- sounds -------------------------------------------------------------------------------------
    def add_task_sound(self, sound: TaskSound) -> TaskSound:
        """Schedule a :class:`TaskSound` (its start must not be in the past)."""
        if sound.start < self.coupling.block_start:
            raise ConfigError(f"task sound {sound.name!r} starts at sample {sound.start}, in the past")
        if any(s.name == sound.name for s in self.task_sounds):
            raise ConfigError(f"a task sound named {sound.name!r} exists already")
        self.coupling.renderer.room.check_inside(sound.position, what=f"task sound {sound.name!r}")
        self.task_sounds.append(sound)
        return sound

    def _start_task_sounds(self) -> list[dict]:
        """Add the task sounds that start in the block about to be rendered."""
        r = self.coupling.renderer
        b0, b1 = r.sample, self.coupling.block_start
        out = []
        for s in self.task_sounds:
            if not s.added and s.start < b1:
                r.add_source(s.name, s.signal, s.position, level_db=s.level_db, start=max(s.start, b0))
                s.added = True
                rec = {"kind": s.kind, "label": s.label, "source": s.name, "time_s": s.start / SAMPLE_RATE, "detail": s.detail}
                self._active.append({"source": s.name, "label": s.label, "start": s.start, "end": s.end, "position": s.position})
                out.append(rec)
        return out

    def _end_task_sounds(self) -> None:
        r = self.coupling.renderer
        linger = round(1.0 * SAMPLE_RATE)
        for s in self.task_sounds:
            if s.added and not s.removed and r.sample > s.end + linger:
                r.remove_source(s.name)
                s.removed = True

    def _track_world_events(self, events: list[SoundEvent]) -> list[dict]:
        out = []
        for ev in events:
            out.append({"kind": ev.kind, "label": ev.label, "source": ev.source, "time_s": ev.sample / SAMPLE_RATE, "detail": ev.detail})
            if ev.kind == "alarm_stop":
                for a in self._active:
                    if a["source"] == ev.source and a["end"] is None:
                        a["end"] = ev.sample
                continue
            end = None if ev.loop else ev.sample + (ev.signal.size if ev.signal is not None else 0)
            self._active.append({"source": ev.source, "label": ev.label, "start": ev.sample, "end": end, "position": None})
        return out

    def sounding(self) -> list[dict]:
        """Ground truth: the sounds playing in the last block, each ``{source, label,
        direction (head frame unit vector), azimuth_deg, elevation_deg, start_s}``."""
        c = self.coupling
        b0 = frame_end_sample(max(c.frame_index - 1, 0))
        b1 = c.block_start
        self._active = [a for a in self._active if a["end"] is None or a["end"] > b0 - SAMPLE_RATE]
        out = []
        for a in self._active:
            if a["start"] < b1 and (a["end"] is None or a["end"] > b0):
                p = a["position"] if a["position"] is not None else c.emitter_position(a["source"])
                v = (np.asarray(p) - c.head_position) @ c.head_rotation
                v = v / max(np.linalg.norm(v), 1e-9)
                az, el = vec_to_sph(v)
                out.append({"source": a["source"], "label": a["label"], "direction": v.astype(np.float32),
                            "azimuth_deg": float(az), "elevation_deg": float(el), "start_s": a["start"] / SAMPLE_RATE})
        return out

    # -- observation and info ---------------------------------------------------------------------------
    def _observation(self) -> dict:
        v = self.view
        pos = np.array([v.joint_angle(j) for j in self._joint_ids], dtype=np.float32)
        vel = np.array([v.joint_velocity(j) for j in self._joint_ids], dtype=np.float32)
        probs = np.zeros(len(CLASSES), np.float32)
        dirs = np.zeros((len(CLASSES), 3), np.float32)
        conf = np.zeros(len(CLASSES), np.float32)
        existence = np.zeros(self._n_directions, np.float32)
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
        obs = {
            "joint_pos": np.clip(pos, -np.pi, np.pi),
            "joint_vel": np.clip(vel, -50.0, 50.0),
            "class_prob": np.clip(probs, 0.0, 1.0),
            "class_dir": np.clip(dirs, -1.0, 1.0),
            "class_conf": np.clip(conf, 0.0, 1.0),
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
        }
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

    # -- helpers for tasks ------------------------------------------------------------------------------------
    def _release_time(self) -> float:
        return self.time_s


class CabinLeverTask(HearingTaskEnv):
    """A cabin task in which one hand starts on its lever and the episode ends when it lets go.

    Subclasses set :attr:`side` and implement :meth:`_judge_release` and :meth:`_judge_running`.
    """

    scene_name = "cabin"
    side = "left"
    background_db_range = (40.0, 55.0)
    """Engine idling and road noise: the cabin's diffuse background, dB SPL per episode."""
    radio_position = (1.62, 0.78, 0.72)
    """Room-frame point (m) of the dashboard radio's loudspeaker (front, a little right)."""

    def _scene_config(self, rng):
        return scene.CabinConfig(gear="P", brake_tooth=0)

    def _setup_world(self, model, data, rng) -> None:
        hold_lever(model, data, self.side)
        self.target_onset_s: float | None = None
        self.release_s: float | None = None
        self.released_state: dict | None = None
        self.false_release = False
        self.reaction_s: float | None = None

    def _apply_special(self, channel: ActionChannel, value: float) -> None:
        side = channel.target.split(":", 1)[1]
        holding = scene.is_grasping(self.model, self.data, side)
        if value > 0.0 and not holding:
            scene.grasp(self.model, self.data, side)
        elif value <= 0.0 and holding:
            scene.release(self.model, self.data, side)
            if side == self.side and self.release_s is None:
                self.release_s = self.time_s  # the moment of the command: the start of this step
                self.released_state = self._lever_state()

    def _task_spaces(self) -> dict:
        return {"grasp": spaces.MultiBinary(2)}

    def _task_obs(self) -> dict:
        return {"grasp": np.array([scene.is_grasping(self.model, self.data, s) for s in names.ARM_SIDES], dtype=np.int8)}

    def _lever_state(self) -> dict:
        raise NotImplementedError

    def _evaluate(self) -> tuple[float, bool]:
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

    def _task_info(self) -> dict:
        info = {
            "success": self.outcome == "success",
            "false_release": bool(self.false_release),
            "target_onset_s": None if self.target_onset_s is None else float(self.target_onset_s),
            "release_s": None if self.release_s is None else float(self.release_s),
            "reaction_s": None if self.reaction_s is None else float(self.reaction_s),
            "holding": bool(scene.is_grasping(self.model, self.data, self.side)),
        }
        info.update(self._lever_state())
        return info

    def add_radio(self, rng: np.random.Generator, start_s: float, level_db: float) -> TaskSound:
        """Speech from the dashboard radio (``human_voice``) at ``start_s``."""
        from acoustic_sim.acoustics import sounds

        return self.add_task_sound(TaskSound(
            name=f"task/radio{len(self.task_sounds)}", label="human_voice", kind="distractor", detail="radio",
            signal=sounds.generate("human_voice", rng), position=np.array(self.radio_position), level_db=level_db,
            start=round(self.at(start_s) * SAMPLE_RATE)))


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


def settle(model: mujoco.MjModel, data: mujoco.MjData, seconds: float) -> None:
    """Run physics for ``seconds`` (setting up a start state), then restart the clock at 0."""
    mujoco.mj_step(model, data, round(seconds / model.opt.timestep))
    data.time = 0.0
    mujoco.mj_forward(model, data)


def hold_lever(model: mujoco.MjModel, data: mujoco.MjData, side: str) -> None:
    """Start state of a cabin task: the hand on its lever (the taught pose at the lever's
    rest angle), settled, and closed on the handle."""
    arm = lever_arm_angles(side, 0.0)
    for joint, q in zip(names.arm_joints(side), arm):
        data.joint(joint).qpos[0] = q
        data.actuator(joint).ctrl[0] = q
    mujoco.mj_forward(model, data)
    settle(model, data, 0.2)
    if not scene.grasp(model, data, side):
        raise ConfigError(f"the {side} hand could not close on its lever at the start of the episode")
    settle(model, data, 0.1)


def db_at(level_db: float, distance_m: float) -> float:
    """Free-field level (dB SPL) at ``distance_m`` of a source of ``level_db`` at 1 m."""
    return float(level_db - 20.0 * math.log10(max(distance_m, 1e-3)))


__all__ = [
    "BLOCK",
    "CLASSES",
    "CONTROL_DT",
    "LEVERS",
    "ROBOT_JOINTS",
    "ActionChannel",
    "ActionLayout",
    "HearingTaskEnv",
    "TaskSound",
    "action_layout",
    "db_at",
    "db_spl_to_pa",
    "hold_lever",
    "lever_arm_angles",
    "lever_motion",
    "make_pipeline",
    "outside_placement",
    "settle",
]
