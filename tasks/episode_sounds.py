"""The task envs' clock and sounds: the episode's time, and sounds played from anywhere.

:class:`EpisodeSounds` is the part of :class:`tasks.base.HearingTaskEnv` that a task (or a
user) calls to place a sound where the world has no emitter (a distractor, a probe) and to
read the ground truth of what is playing. It works on the episode's
:class:`~acoustic_sim.loop.HearingLoop` and its :class:`~tasks.task_sounds.Soundscape`
(built by :meth:`~tasks.base.HearingTaskEnv.reset`: the env's ``coupling``, ``hearing``,
``soundscape`` and ``start_s``).
"""

from __future__ import annotations

import math

import numpy as np

from acoustic_sim.errors import ConfigError
from tasks.task_sounds import TaskSound


class EpisodeSounds:
    """The env's clock and its task sounds (a base of :class:`tasks.base.HearingTaskEnv`)."""

    # -- time ---------------------------------------------------------------------------------------
    def at(self, t: float) -> float:
        """Project-clock time (s) of ``t`` seconds after the episode's start."""
        return self.start_s + float(t)

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
            The sound class (one of :data:`tasks.observations.CLASSES`).
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


def db_at(level_db: float, distance_m: float) -> float:
    """Free-field level (dB SPL) at ``distance_m`` of a source of ``level_db`` at 1 m."""
    return float(level_db - 20.0 * math.log10(max(distance_m, 1e-3)))


__all__ = ["EpisodeSounds", "db_at"]
