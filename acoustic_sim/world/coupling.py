"""The coupling: the MuJoCo world drives the acoustic world, once per control step.

One control step is one ear frame (16 ms at 62.5 Hz): ``n`` physics steps of the model's
timestep (8 of 2 ms), then one block of binaural audio of 705 or 706 samples on the
project clock (DESIGN.md). :meth:`Coupling.advance` runs the physics and does everything
but the audio: it traces the mechanisms at every physics step, turns the traces and the
scheduled requests into :class:`~acoustic_sim.world.events.SoundEvent` s, reads the ear and
source poses from the view, expresses them in the acoustic room's frame and hands them to
the renderer. :meth:`Coupling.render` then mixes the events' sounds into their emitters
and renders the block; :meth:`Coupling.step` does both.

Room frame. The acoustic room is the scene's box-typed air-volume site (``car/interior`` or
``room_interior``), with the renderer's origin at its (-x, -y, -z) corner and its axes
(:class:`~acoustic_sim.world.room_box.RoomFrame`). The renderer's
:class:`~acoustic_sim.acoustics.room.Room` must have the box's dimensions (the scene builds
it from the same site, so the two never disagree; this is checked).

Emitters. Every emitter (:data:`~acoustic_sim.world.events.EMITTERS`) that has sounded is one
renderer source fed through a ring buffer, which :meth:`render` fills for exactly the samples
of the block about to be rendered (:mod:`acoustic_sim.world.emitter_rings`).

Outside emitters (the car horn) play by :meth:`Coupling.through_body`, the one law for sounds
from beyond the walls (a task's other vehicle follows it too, through
:class:`~acoustic_sim.world.soundscape.Soundscape`): just inside the walls where the straight
line from their site to the head enters the room. History: docs/notes/outside_sounds.md.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE, FrameEnds, frame_end_sample
from acoustic_sim.world import actuation, names
from acoustic_sim.world.egonoise import EgoNoiseConfig, MotorEgoNoise
from acoustic_sim.world.emitter_rings import EmitterRing, release_samples
from acoustic_sim.world.events import EMITTERS, EventsConfig, SoundEvent, SoundEvents
from acoustic_sim.world.room_box import RoomFrame
from acoustic_sim.world.view import WorldView

HEAD_POSITION_TOL = 1e-4
"""Head moves (m, per coordinate) below this are not sent to the renderer."""

HEAD_ROTATION_TOL = 1e-4
"""Head turns (rotation-matrix entries, about rad) below this are not sent to the renderer."""


class Coupling:
    """Drive a binaural renderer from a MuJoCo world, one control step at a time.

    Parameters
    ----------
    model : mujoco.MjModel
        A composed scene (``world.scenes``); its timestep must divide the 16 ms control step.
    data : mujoco.MjData
    renderer : acoustic_sim.acoustics.renderer.BinauralRenderer or None
        Renders the ears; its room must be the scene's air volume (same dimensions) and its
        clock at a frame boundary. ``None`` runs the world without audio (events and poses
        are still computed).
    rng : numpy.random.Generator
        Draws every event sound (through :class:`SoundEvents`); nothing else.
    events_config : EventsConfig, optional
    interior_site : str, optional
        The box site of the acoustic room; default ``car/interior`` if the scene has it,
        else ``room_interior``.
    outside_margin_m : float
        How far inside the walls (m) outside emitters play from, 0.05-0.5.
    move_threshold_m : float
        A source is moved in the renderer when its anchor moved more than this (m) since
        the last move (about a quarter sample of delay at 1 mm); 0-0.05.
    idle_release_s : float
        A silent emitter's source is removed after this (s) plus the room's reverberation.

    Attributes
    ----------
    view : WorldView
    events : SoundEvents
        Schedule calls, key turns and distractors here.
    ego_noise : MotorEgoNoise or None
        The renderer's ego-noise when it is a :class:`MotorEgoNoise`; updated every step.
    frame : RoomFrame
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        renderer,
        *,
        rng: np.random.Generator,
        events_config: EventsConfig | None = None,
        interior_site: str | None = None,
        outside_margin_m: float = 0.1,
        move_threshold_m: float = 0.002,
        idle_release_s: float = 1.0,
    ) -> None:
        self.model, self._data = model, data
        self.view = WorldView(model, data)
        actuation.forward(model, data)  # poses of a fresh MjData are not computed yet
        self.renderer = renderer
        self.sample_rate = renderer.sample_rate if renderer is not None else SAMPLE_RATE
        dt = float(model.opt.timestep)
        ratio = 1.0 / (FRAME_RATE * dt)
        if not np.isclose(ratio, round(ratio), rtol=0, atol=1e-9) or round(ratio) < 1:
            raise ConfigError(f"the physics timestep {dt} s must divide the {1e3 / FRAME_RATE:g} ms control step")
        self.n_substeps = round(ratio)
        self.samples_per_substep = self.sample_rate / (FRAME_RATE * self.n_substeps)
        for what, value, lo, hi in (("outside_margin_m", outside_margin_m, 0.05, 0.5),
                                    ("move_threshold_m", move_threshold_m, 0.0, 0.05),
                                    ("idle_release_s", idle_release_s, 0.0, 60.0)):
            if not np.isfinite(value) or not lo <= value <= hi:
                raise ConfigError(f"Coupling: {what} must be {lo}..{hi}, got {value}")
        self.outside_margin_m = float(outside_margin_m)
        self.move_threshold_m = float(move_threshold_m)

        if interior_site is None:
            interior_site = names.CABIN_INTERIOR_SITE if self.view.has_site(names.CABIN_INTERIOR_SITE) else names.ROOM_INTERIOR_SITE
        if not self.view.has_site(interior_site):
            raise ConfigError(
                f"the scene has no air-volume site ({names.CABIN_INTERIOR_SITE!r} or {names.ROOM_INTERIOR_SITE!r}) "
                "to place the acoustic room"
            )
        self.interior_site = interior_site
        self.frame = RoomFrame.from_box(*self.view.site_box(interior_site))
        if renderer is not None:
            room = renderer.room
            if room.anechoic or not np.allclose(room.dimensions, self.frame.dimensions, atol=1e-3):
                raise ConfigError(
                    f"the renderer's room {room.name!r} ({'anechoic' if room.anechoic else room.dimensions}) is not the scene's "
                    f"air volume {interior_site!r} ({tuple(np.round(self.frame.dimensions, 3))} m): build it from the scene"
                )
            if renderer.sample != frame_end_sample(renderer.frame, renderer.sample_rate):
                raise ConfigError(f"the renderer's clock (sample {renderer.sample}) is not at a frame boundary")
        self._release_samples = release_samples(idle_release_s, renderer.room if renderer is not None else None, self.sample_rate)
        self.frame_index = renderer.frame if renderer is not None else 0

        self.events = SoundEvents.from_view(self.view, rng, events_config, sample_rate=self.sample_rate)
        self.ego_noise = renderer.ego_noise if renderer is not None and isinstance(renderer.ego_noise, MotorEgoNoise) else None
        if self.ego_noise is not None and self.ego_noise.actuator_indices is None:
            raise ConfigError("the renderer's MotorEgoNoise must be built with MotorEgoNoise.from_view for this world")
        self._emitters = {
            e.name: EmitterRing(e.name, e.anchor, e.outside) for e in EMITTERS.values() if e.name in self.events.emitters
        }
        self._gear_trace = [0.0] * self.n_substeps  # mechanism angles (rad) after each physics step
        self._brake_trace = [0.0] * self.n_substeps
        self._pawl_trace = [0.0] * self.n_substeps
        self.head_position, self.head_rotation = np.zeros(3), np.eye(3)
        """Head centre (m, room frame) and orientation (head to room) after the last step."""
        self._sent_head: tuple[np.ndarray, np.ndarray] | None = None
        self.scene_info = None
        """The :class:`~acoustic_sim.world.scenes.SceneInfo` when built by :meth:`from_scene`."""
        self.last_events: list[SoundEvent] = []
        """The events of the last step."""
        self.reset_events()

    @classmethod
    def from_scene(cls, name: str, *, rng: np.random.Generator, hrtf="kemar", scene_config=None,
                   ego_noise: EgoNoiseConfig | bool | None = True, background: bool = True, late: bool = True,
                   events_config: EventsConfig | None = None) -> Coupling:
        """Load a composed scene and wire it to a renderer of its own acoustic room.

        Parameters
        ----------
        name : str
            ``cabin`` or ``room`` (:data:`acoustic_sim.world.scenes.SCENES`).
        rng : numpy.random.Generator
            Spawns the renderer's generator (noise, late tails) and the events' (sounds).
        hrtf : str or HRTF
            The ears: an HRTF or a name for :meth:`HRTF.load` (default the bundled KEMAR).
        scene_config : CabinConfig or RoomConfig, optional
            The scene's initial state (:func:`acoustic_sim.world.scenes.load_scene`).
        ego_noise : EgoNoiseConfig or bool
            ``True`` (default) for the default motor noise, a config for another, ``False``
            or ``None`` for none.
        background, late : bool
            The renderer's room background noise and late reverberation.
        events_config : EventsConfig, optional

        Returns
        -------
        Coupling
            With ``model``, ``data``, ``renderer`` and :attr:`scene_info` (:meth:`wired`).
        """
        from acoustic_sim.acoustics.hrtf import HRTF
        from acoustic_sim.world.scenes import load_scene

        if not isinstance(rng, np.random.Generator):
            raise ConfigError(f"Coupling.from_scene needs a numpy.random.Generator, got {type(rng).__name__}")
        model, data, info = load_scene(name, config=scene_config)
        ears = hrtf if isinstance(hrtf, HRTF) else HRTF.load(hrtf)
        render_rng, events_rng = rng.spawn(2)
        return cls.wired(model, data, info, ears=ears, render_rng=render_rng, events_rng=events_rng, ego_noise=ego_noise,
                         background=background, late=late, events_config=events_config)

    @classmethod
    def wired(cls, model, data, info, *, ears, render_rng: np.random.Generator, events_rng: np.random.Generator,
              room=None, ego_noise: EgoNoiseConfig | bool | None = True, background: bool = True, late: bool = True,
              events_config: EventsConfig | None = None) -> Coupling:
        """A loaded scene (``load_scene``'s model, data and info) wired to a renderer of its
        acoustic room: ``room`` (default ``info.room``; a task changes its background level),
        ``ears`` (an HRTF), the renderer drawing from ``render_rng`` and the events from
        ``events_rng``; the other arguments as in :meth:`from_scene`. The env's reset and
        :meth:`from_scene` both build their world here."""
        from acoustic_sim.acoustics.renderer import BinauralRenderer

        ego = None
        if ego_noise is not None and ego_noise is not False:
            config = ego_noise if isinstance(ego_noise, EgoNoiseConfig) else None
            ego = MotorEgoNoise.from_view(WorldView(model, data), config, sample_rate=ears.sample_rate)
        renderer = BinauralRenderer(ears, info.room if room is None else room, rng=render_rng, sample_rate=ears.sample_rate,
                                    background=background, late=late, ego_noise=ego)
        coupling = cls(model, data, renderer, rng=events_rng, events_config=events_config)
        coupling.scene_info = info
        return coupling

    @property
    def data(self) -> mujoco.MjData:
        """The simulation state (write it through :mod:`acoustic_sim.world.actuation`; read it through :attr:`view`)."""
        return self._data

    # -- clock ----------------------------------------------------------------------------------
    @property
    def frame_index(self) -> int:
        """Control steps since the project clock's origin: the next block is this + 1."""
        return self._frame_index

    @frame_index.setter
    def frame_index(self, k: int) -> None:
        self._frame_index = int(k)
        if getattr(self, "_ends", None) is None:
            self._ends = FrameEnds(self.sample_rate)
        self.block_start = self._ends(self._frame_index)
        """First sample of the next block on the project clock."""

    @property
    def time_s(self) -> float:
        """Project-clock time (s) of the next block's start."""
        return self.block_start / self.sample_rate

    def reset_events(self) -> None:
        """Restart the events at the current state (after a reset of ``data``): mechanisms
        are re-read without events, requests and sounding emitters are dropped.

        Runs ``mj_forward`` first, so that poses and actuator forces match the state."""
        actuation.forward(self.model, self._data)
        v = self.view
        self.events.reset(
            sample=self.block_start,
            gear_angle=v.gearshift_angle() if v.gearshift_geometry is not None else None,
            brake_angle=v.brake_angle() if v.ratchet_geometry is not None else None,
            pawl_angle=v.pawl_angle() if v.ratchet_geometry is not None else None,
        )
        for e in self._emitters.values():
            e.silence(self.block_start)
        self._sync_poses()

    # -- stepping -------------------------------------------------------------------------------
    def advance(self) -> list[SoundEvent]:
        """Run one control step of physics and couple it, without rendering audio.

        Returns
        -------
        list of SoundEvent
            The events that start (or stop) in this step's block.
        """
        m, d, v = self.model, self._data, self.view
        for e in self._emitters.values():
            e.drop_finished(self.block_start)
        gear = v.gearshift_geometry is not None
        brake = v.ratchet_geometry is not None
        for j in range(self.n_substeps):
            actuation.step(m, d)
            if gear:
                self._gear_trace[j] = v.gearshift_angle()
            if brake:
                self._brake_trace[j] = v.brake_angle()
                self._pawl_trace[j] = v.pawl_angle()
        first = self.frame_index * self.n_substeps + 1
        positions = [(first + j) * self.samples_per_substep for j in range(self.n_substeps)]
        self.frame_index += 1
        end = self.block_start
        events = self.events.process(
            end, positions, gear_angles=self._gear_trace if gear else None,
            brake_angles=self._brake_trace if brake else None, pawl_angles=self._pawl_trace if brake else None,
        )
        for ev in events:
            self._apply(ev)
        self._sync_poses()
        if self.ego_noise is not None:
            self.ego_noise.update(v)
        self.last_events = events
        return events

    def render(self) -> np.ndarray:
        """Render the block of the last :meth:`advance`: eardrum pressure (2, n) in Pa."""
        r = self.renderer
        if r is None:
            raise ConfigError("this coupling has no renderer (it was built with renderer=None)")
        b0, b1 = r.sample, self.block_start
        if b1 - b0 <= 0 or r.frame != self.frame_index - 1:
            raise ConfigError(
                f"render() must follow one advance(): the renderer is at frame {r.frame}, the world at {self.frame_index}"
            )
        for e in self._emitters.values():
            e.feed(r, b0, b1, self._release_samples)
        return r.render_block(b1 - b0)

    def step(self) -> np.ndarray:
        """:meth:`advance` then :meth:`render`: one control step, one block (2, n) Pa."""
        self.advance()
        return self.render()

    # -- sounds from outside the room ---------------------------------------------------------------
    def through_body(self, point_room, level_db: float, *, margin: float | None = None) -> tuple[np.ndarray, float]:
        """Where and how loud a source outside the acoustic room plays inside it: the one
        law for sounds from beyond the walls (the car horn here, a task's other vehicle
        through :class:`~acoustic_sim.world.soundscape.Soundscape`).

        From the point ``margin`` inside the walls (just inside the windscreen) where the
        straight line from ``point_room`` to the head (:attr:`head_position`, now) enters
        the room (:meth:`RoomFrame.entry_point`), at ``level_db`` minus the body's
        transmission loss (``events.config.transmission_loss_db``) and minus the spreading
        ``20 log10(max(d, 1 m) / 1 m)`` dB from the source to that point: the body
        re-radiates what reaches it, less what it stops, and of all the paths through it the
        straight one arrives first, so the first wavefront, from which a listener takes a
        sound's direction, comes from the source's own direction.

        Parameters
        ----------
        point_room : array_like, shape (3,)
            The source, room frame (m), outside the room.
        level_db : float
            dB SPL at 1 m of the source, outside.
        margin : float, optional
            How far inside the walls (m); default :attr:`outside_margin_m`.

        Returns
        -------
        position : numpy.ndarray, shape (3,)
            Room frame (m).
        level_db : float
            dB SPL at 1 m from ``position``.
        """
        p = np.asarray(point_room, dtype=float)
        inside = self.frame.entry_point(p, self.head_position, self.outside_margin_m if margin is None else margin)
        d = float(np.linalg.norm(p - inside))
        return inside, level_db - self.events.config.transmission_loss_db - 20.0 * math.log10(max(d, 1.0))

    # -- internals ------------------------------------------------------------------------------
    def _apply(self, ev: SoundEvent) -> None:
        e = self._emitters[ev.source]
        if ev.kind == "alarm_stop":
            e.stop_loops(ev.sample)
            return
        e.play(ev.signal, ev.sample, ev.level_db + (self._anchor(e)[1] if e.outside else 0.0), ev.loop, self.sample_rate)

    def _anchor(self, e: EmitterRing) -> tuple[np.ndarray, float]:
        """Room-frame position (m) an emitter plays from and its level change (dB): for
        outside emitters, :meth:`through_body` (its level change: the law applied to 0 dB)."""
        p = self.frame.to_room(self.view.site_position(e.anchor))
        if not e.outside:
            return p, 0.0
        return self.through_body(p, 0.0)

    def _sync_poses(self) -> None:
        """Head and emitter poses from the view, in the room frame, to the renderer."""
        v, f, r = self.view, self.frame, self.renderer
        centre, rot = v.head_pose()
        position, rotation = f.to_room(centre), f.rotation_to_room(rot)
        # The renderer re-derives its responses when the pose changes; physics jitters the head
        # by micrometres every step, so only moves beyond HEAD_POSITION_TOL / HEAD_ROTATION_TOL
        # (far below the renderer's 1/8-sample delay and 0.5 deg direction resolution) are sent.
        if r is not None and (
            self._sent_head is None
            or np.max(np.abs(position - self._sent_head[0])) > HEAD_POSITION_TOL
            or np.max(np.abs(rotation - self._sent_head[1])) > HEAD_ROTATION_TOL
        ):
            r.set_head_pose(position, rotation)
            self._sent_head = (position, rotation)
        self.head_position, self.head_rotation = position, rotation
        for e in self._emitters.values():
            if not e.sounds and e.ring is None and e.position is not None:
                continue  # idle and not in the renderer: nothing to keep up to date
            e.follow(self._anchor(e)[0], self.move_threshold_m, r)

    # -- inspection -----------------------------------------------------------------------------
    def source_positions(self) -> dict[str, np.ndarray]:
        """Room-frame positions (m) of the emitters that have a renderer source."""
        return {e.name: e.position.copy() for e in self._emitters.values() if e.ring is not None}

    def emitter_position(self, name: str) -> np.ndarray:
        """Room-frame position (m) an emitter plays from now (outside ones: inside the wall)."""
        if name not in self._emitters:
            raise ConfigError(f"this scene has no emitter {name!r}; emitters: {sorted(self._emitters)}")
        return self._anchor(self._emitters[name])[0]
