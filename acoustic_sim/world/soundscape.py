"""Sounds scheduled anywhere in the acoustic room, and the ground truth of what is sounding.

The world's emitters (:data:`acoustic_sim.world.events.EMITTERS`) sound from sites of the
scene: the reverse alarm's speaker, the ratchet's pawl, the person's mouth, the ignition,
the horn; the coupling owns their renderer sources. Every other sound (a task's
distractors: another car's reverse alarm behind, a turn-signal relay under the dashboard,
the radio, the room's loudspeaker) is a :class:`ScheduledSound` of a :class:`Soundscape`,
the one owner of those renderer sources: :meth:`Soundscape.schedule_sound` validates and
places it, the source is added in the control block in which the sound starts, sounds from
its start sample on, and is removed once the sound and its reverberation are over. The
hearing loop (:class:`acoustic_sim.loop.HearingLoop`) drives it once per control step, so
no caller touches the renderer.

Positions are in metres, in one of two frames:

- ``"room"``: the acoustic room's frame, the renderer's (origin at a corner of the scene's
  air volume, axes the box's; :class:`~acoustic_sim.world.room_box.RoomFrame`), in which
  :attr:`Coupling.head_position <acoustic_sim.world.coupling.Coupling.head_position>` is given;
- ``"world"``: MuJoCo's world frame (z up), e.g. a site's position read from the view.

A point outside the acoustic room (another vehicle) plays by the coupling's one law for
sounds from beyond the walls, the car horn's
(:meth:`Coupling.through_body <acoustic_sim.world.coupling.Coupling.through_body>`): from
where the straight line from it to the head enters the room, just inside the walls, at its
level minus the car body's transmission loss and minus the spreading to that point, so
the first wavefront through the body comes from the source's own direction.

The soundscape also keeps the ground truth: the event records of the world's events and of
the scheduled sounds as they start (:meth:`Soundscape.begin_block`), and the sounds playing
with their true directions from the head (:meth:`Soundscape.sounding`).

(Moved from ``tasks/soundscape.py`` (now ``tasks/task_sounds.py``), which keeps the tasks' names for it, in issue 30: the
library's loop must own the sounds, and the library imports no task code.)
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from acoustic_sim.acoustics.render_source import mono_signal
from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import frame_end_sample, vec_to_sph

if TYPE_CHECKING:  # for the annotations only: importing this module imports no MuJoCo (its OpenGL backend)
    from acoustic_sim.world.coupling import Coupling
    from acoustic_sim.world.events import SoundEvent

FRAMES = ("room", "world")
"""Frames a scheduled sound's position may be given in."""

SOURCE_PREFIX = "task/"
"""Renderer source names of scheduled sounds start with this (world emitters' names never do;
the sounds are a task's, whoever schedules them)."""


@dataclasses.dataclass
class ScheduledSound:
    """A sound played from a fixed point of the acoustic room (``tasks.task_sounds.TaskSound``).

    Attributes
    ----------
    name : str
        Renderer source name (``task/<name>``); unique per episode.
    label : str
        Its sound class (one of ``SOUND_CLASSES``): what a classifier should say.
    kind : str
        What it is, for the ground truth (``distractor``).
    detail : str
        Free text (``another vehicle's beeper, behind``, ``radio``).
    signal : numpy.ndarray, shape (n,)
        Unit-RMS mono signal at the project rate.
    position : numpy.ndarray, shape (3,)
        Room frame (m): where it plays from (inside the room).
    level_db : float
        dB SPL at 1 m from ``position`` of the unit-RMS signal.
    start : int
        Start sample on the project clock.
    added, removed : bool
        Whether its renderer source has been added, and removed again.
    """

    name: str
    label: str
    kind: str
    detail: str
    signal: np.ndarray | None
    position: np.ndarray
    level_db: float
    start: int
    added: bool = False
    removed: bool = False
    later: object = None
    """A zero-argument callable that gives ``signal`` when the sound starts (None: given)."""

    @property
    def end(self) -> int:
        """First sample after the signal (project clock)."""
        return self.start + int(self.signal.size)


class Soundscape:
    """The scheduled sounds and the ground truth of one episode, over a coupling.

    Once per control step, after ``coupling.advance()``: :meth:`begin_block` (it adds the
    sounds that start in the block about to be rendered), then ``coupling.render()``, then
    :meth:`end_block`. :class:`acoustic_sim.loop.HearingLoop` does this; call it yourself
    only when driving a coupling by hand.

    Parameters
    ----------
    coupling : Coupling
        It must have a renderer.
    linger_s : float
        A scheduled sound's renderer source is removed this long (s, 0-10) after its signal
        ends, when its reverberation has died away (the scenes' RT60 is 0.5 s at most).
    """

    def __init__(self, coupling: Coupling, *, linger_s: float = 1.0) -> None:
        if coupling.renderer is None:
            raise ConfigError("a Soundscape needs a coupling with a renderer")
        if not (np.isfinite(linger_s) and 0.0 <= linger_s <= 10.0):
            raise ConfigError(f"linger_s must be 0..10 s, got {linger_s!r}")
        self.coupling = coupling
        self.linger = round(linger_s * coupling.sample_rate)
        self.sounds: list[ScheduledSound] = []
        """Every sound scheduled, in order."""
        self._active: list[dict] = []  # ground truth: sounds playing (world events and scheduled sounds)

    # -- scheduling ---------------------------------------------------------------------------
    def schedule_sound(self, name: str, label: str, signal, position, t: float, level_db: float, *,
                       frame: str = "room", outside: bool = False, kind: str = "distractor", detail: str = "") -> ScheduledSound:
        """Play ``signal`` from a fixed point from time ``t`` on.

        Parameters
        ----------
        name : str
            Short name, unique in the episode: the renderer source and the ground truth's
            ``source`` are ``task/<name>``.
        label : str
            The sound class (one of ``SOUND_CLASSES``): the ground truth's label.
        signal : array_like, shape (n,), or callable
            Unit-RMS mono signal at the coupling's sample rate (44100 Hz), finite, n >= 1; or a
            zero-argument callable that returns it when the sound starts (synthesized only if
            the episode gets there: :meth:`SoundEvents.draw_later
            <acoustic_sim.world.events.SoundEvents.draw_later>`).
        position : array_like, shape (3,)
            Where it plays from (m), in ``frame``; inside the room at least 0.05 m from
            every wall, unless ``outside``.
        t : float
            Start time (s) on the project clock, not before the next block
            (``coupling.time_s``); rounded to the nearest sample.
        level_db : float
            dB SPL at 1 m of the unit-RMS signal, -20..160; for an ``outside`` sound, at
            1 m outside, before the body's transmission loss.
        frame : {"room", "world"}
            The frame of ``position`` (see the module docstring).
        outside : bool
            ``position`` lies outside the acoustic room (another vehicle): the sound plays
            through the body (:meth:`Coupling.through_body
            <acoustic_sim.world.coupling.Coupling.through_body>`).
        kind : str
            The ground truth's event kind (``distractor``).
        detail : str
            Free text for the ground truth.

        Returns
        -------
        ScheduledSound
            Its ``position`` and ``level_db`` are where and how loud it plays in the room.

        Raises
        ------
        ConfigError
            If an argument is out of range, the name is taken, ``t`` is in the past, or the
            position is outside the room (inside it, with ``outside``).
        """
        c = self.coupling
        what = f"schedule_sound({name!r})"
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"schedule_sound: name must be a non-empty string, got {name!r}")
        source = SOURCE_PREFIX + name
        if any(s.name == source for s in self.sounds):
            raise ConfigError(f"{what}: a scheduled sound named {name!r} exists already in this episode")
        if label not in SOUND_CLASSES:
            raise ConfigError(f"{what}: unknown sound class {label!r}; valid: {', '.join(SOUND_CLASSES)}")
        later = signal if callable(signal) else None
        x = None if later is not None else mono_signal(signal, what)
        if not (isinstance(level_db, (int, float, np.floating, np.integer)) and np.isfinite(level_db) and -20.0 <= level_db <= 160.0):
            raise ConfigError(f"{what}: level_db must be -20..160 dB SPL at 1 m, got {level_db!r}")
        if not (isinstance(t, (int, float, np.floating, np.integer)) and np.isfinite(t)):
            raise ConfigError(f"{what}: t must be a finite time in s, got {t!r}")
        start = round(t * c.sample_rate)
        if start < c.block_start:
            raise ConfigError(f"{what}: t = {t:.4f} s is in the past (the next block starts at {c.time_s:.4f} s)")
        if frame not in FRAMES:
            raise ConfigError(f"{what}: frame must be 'room' or 'world', got {frame!r}")
        p = np.asarray(position, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ConfigError(f"{what}: position must be 3 finite coordinates in m, got {position!r}")
        if frame == "world":
            p = c.frame.to_room(p)
        level = float(level_db)
        if outside:
            if np.all(p >= 0.0) and np.all(p <= c.frame.dimensions):
                raise ConfigError(f"{what}: position {tuple(np.round(p, 3))} (room frame) is inside the room; "
                                  "outside=True is for sources beyond its walls")
            p, level = c.through_body(p, level)
            if level < -20.0:
                raise ConfigError(f"{what}: through the body it would play at {level:.1f} dB SPL (below -20): too far or too quiet")
        else:
            p = c.renderer.room.check_inside(p, what=f"{what}: position (room frame)")
        sound = ScheduledSound(name=source, label=label, kind=str(kind), detail=str(detail), signal=x, position=p,
                               level_db=level, start=start, later=later)
        self.sounds.append(sound)
        return sound

    # -- the control step ---------------------------------------------------------------------
    def begin_block(self, events: list[SoundEvent]) -> list[dict]:
        """Record the world's events of the block about to be rendered and add the scheduled
        sounds that start in it to the renderer.

        Parameters
        ----------
        events : list of SoundEvent
            What ``coupling.advance()`` returned.

        Returns
        -------
        list of dict
            Event records ``{kind, label, source, time_s, detail}``: the world's events,
            then the scheduled sounds that start.
        """
        return self._track_world_events(events) + self._start_task_sounds()

    def end_block(self) -> None:
        """Remove the renderer sources of scheduled sounds that are over (``linger_s`` after their end)."""
        r = self.coupling.renderer
        for s in self.sounds:
            if s.added and not s.removed and r.sample > s.end + self.linger:
                r.remove_source(s.name)
                s.removed = True

    def forget(self) -> None:
        """Drop the ground truth of what is sounding (after the ears' warm-up)."""
        self._active.clear()

    def _start_task_sounds(self) -> list[dict]:
        r = self.coupling.renderer
        b0, b1 = r.sample, self.coupling.block_start
        out = []
        for s in self.sounds:
            if not s.added and s.start < b1:
                if s.signal is None:
                    s.signal = mono_signal(s.later(), f"schedule_sound({s.name[len(SOURCE_PREFIX):]!r})")
                r.add_source(s.name, s.signal, s.position, level_db=s.level_db, start=max(s.start, b0))
                s.added = True
                self._active.append({"source": s.name, "label": s.label, "start": s.start, "end": s.end, "position": s.position})
                out.append({"kind": s.kind, "label": s.label, "source": s.name, "time_s": s.start / self.coupling.sample_rate,
                            "detail": s.detail})
        return out

    def _track_world_events(self, events: list[SoundEvent]) -> list[dict]:
        rate = self.coupling.sample_rate
        out = []
        for ev in events:
            out.append({"kind": ev.kind, "label": ev.label, "source": ev.source, "time_s": ev.sample / rate, "detail": ev.detail})
            if ev.kind == "alarm_stop":
                for a in self._active:
                    if a["source"] == ev.source and a["end"] is None:
                        a["end"] = ev.sample
                continue
            end = None if ev.loop else ev.sample + (ev.signal.size if ev.signal is not None else 0)
            self._active.append({"source": ev.source, "label": ev.label, "start": ev.sample, "end": end, "position": None})
        return out

    # -- ground truth -------------------------------------------------------------------------
    def sounding(self) -> list[dict]:
        """The sounds playing in the last block, each ``{source, label, direction (head
        frame unit vector, float32), azimuth_deg, elevation_deg, start_s}``."""
        c = self.coupling
        b0 = frame_end_sample(max(c.frame_index - 1, 0))
        b1 = c.block_start
        rate = c.sample_rate
        self._active = [a for a in self._active if a["end"] is None or a["end"] > b0 - rate]
        out = []
        for a in self._active:
            if a["start"] < b1 and (a["end"] is None or a["end"] > b0):
                p = a["position"] if a["position"] is not None else c.emitter_position(a["source"])
                v = (np.asarray(p) - c.head_position) @ c.head_rotation
                v = v / max(np.linalg.norm(v), 1e-9)
                az, el = vec_to_sph(v)
                out.append({"source": a["source"], "label": a["label"], "direction": v.astype(np.float32),
                            "azimuth_deg": float(az), "elevation_deg": float(el), "start_s": a["start"] / rate})
        return out


__all__ = ["FRAMES", "SOURCE_PREFIX", "ScheduledSound", "Soundscape"]
