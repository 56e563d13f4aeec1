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

    Why the line of sight (since 2026-12-04, session 21): of the paths through the body the
    straight one from the source to the head arrives first, and the first wavefront gives a
    sound its direction, so a source beside the cabin is heard from its own direction. Until
    then a source played from the point inside the walls nearest to it, which brought one
    2-6 m beside the cabin and 0.5-1 m ahead of the head in through the window next to it,
    19-35 deg from straight ahead, where the line of sight gives 68-86 deg (its path that
    way is 0.2-0.5 m, 0.7-1.5 ms, longer). A task sound is placed when it is scheduled
    (the head's position then); the car horn, the coupling's emitter, follows the head. The
    change moved ReverseAlarm's beepers on the left onto the front's mirror image from the
    then policy's listening pose (45 deg right), so the policy changed with it: it now
    listens 22 deg right and accepts a window of lateral angles
    (:class:`policies.scripted.ScriptedReverseAlarm`; measurements: docs/notes/alarm_policy.md). Fast models
    under this law with the old policy, seeds 1000-1099 (89 with no false release under the
    old law): 87 with 2 false releases (test seeds 100-119: 17/20 with 2); 30 deg right 85
    with 2; 25 deg right 78 with none; 20 deg right 54; 25 deg right without the mirror
    image 14 (the alarm near the median plane is mostly placed behind). The 16-bin fast bank
    of then with the lateral rule: 10 of 20 on the test seeds, 73 on 1000-1099: near the
    median plane its lateral angles scatter, so the tests' bank became the jittered 32-bin
    one (:data:`~acoustic_sim.auditory.ssdenet.recipes.FAST`).
    ParkingBrake has no outside sounds (100-119 unchanged).

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
