"""The tasks' sounds placed anywhere, and the ground truth of what is sounding: the tasks' names.

The machinery is the library's (:mod:`acoustic_sim.world.soundscape`: scheduling a signal at
a point and time, adding it to the renderer as it starts, forgetting it, the ground truth),
driven once per step by the env's :class:`~acoustic_sim.loop.HearingLoop`, the one owner of
those renderer sources; a task schedules through :meth:`tasks.base.HearingTaskEnv.schedule_sound`.
Here are the names the tasks use for it (:class:`TaskSound`, renderer sources ``task/<name>``)
and :func:`outside_placement`, the law for sounds from outside the cabin as the tasks see it,
with the history of what it did to them.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.world.coupling import Coupling
from acoustic_sim.world.soundscape import FRAMES, SOURCE_PREFIX, ScheduledSound, Soundscape

TaskSound = ScheduledSound
"""A sound the task plays from a fixed point of the acoustic room
(:class:`acoustic_sim.world.soundscape.ScheduledSound`)."""


def outside_placement(coupling: Coupling, point_room, level_db: float, margin: float | None = None) -> tuple[np.ndarray, float]:
    """Where and how loud a source outside the acoustic room plays inside it.

    The coupling's one law for sounds from beyond the walls, the car horn's
    (:meth:`Coupling.through_body <acoustic_sim.world.coupling.Coupling.through_body>`,
    which :meth:`Soundscape.schedule_sound` applies to an ``outside`` sound): from the point
    ``margin`` inside the walls where the straight line from ``point_room`` to the head
    (``coupling.head_position``, at the time of the call) enters the room
    (:meth:`~acoustic_sim.world.room_box.RoomFrame.entry_point`), at ``level_db`` minus the
    body's transmission loss and minus the spreading ``20 log10(max(d, 1 m))`` from the
    source to that point.

    Why the line of sight: the first wavefront gives a sound its direction, and of the paths
    through the body the straight one arrives first. A task sound is placed when it is
    scheduled (the head's position then); the car horn, the coupling's emitter, follows the
    head. What the change did to ReverseAlarm and its policy: docs/notes/outside_sounds.md.

    Parameters
    ----------
    coupling : Coupling
    point_room : array_like, shape (3,)
        The source, room frame (m), outside the room.
    level_db : float
        dB SPL at 1 m of the source, outside.
    margin : float, optional
        How far inside the walls (m); default the coupling's ``outside_margin_m``.

    Returns
    -------
    position : numpy.ndarray, shape (3,)
        Room frame (m).
    level_db : float
        dB SPL at 1 m from ``position``.
    """
    return coupling.through_body(point_room, level_db, margin=margin)


__all__ = ["FRAMES", "SOURCE_PREFIX", "Soundscape", "TaskSound", "outside_placement"]
