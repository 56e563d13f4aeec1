"""The crowd of the CallResponse task: where its people stand, and when one is looked at.

Placement (:func:`place_crowd`): the wheelchair somewhere in the room, each person at a
random bearing out of the robot's view and apart from the others, the loudspeaker away from
the caller. Sight (:class:`Sight`): whether a person's head is inside the right eye camera's
field of view and not occluded (a geometric check with ``mj_ray``, no rendering), and how
fast the gaze moves. The look rule (:class:`Look`): a person is looked at when in view with
the gaze still for ``look_s``; whoever was in view when the call started counts only once
the gaze has left them.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scenes

ROOM_SIZE = (6.0, 5.0)
"""Floor size (m) of the ``room`` scene (its air volume's x and y)."""

OUT_OF_VIEW_DEG = 50.0
"""Every person starts at least this far (deg of bearing) from the robot's line of sight."""

APART_DEG = 60.0
"""The people stand at least this far apart (deg of bearing from the wheelchair)."""

LOOK_S = 0.25
"""A look: a person in view while the gaze is still (below :data:`STILL_DEG_S`), this long (s).
A turn sweeping past someone is not a look (a saccade does not fixate)."""

STILL_DEG_S = 30.0
"""The gaze is still below this angular speed (deg/s, the right eye camera's forward axis in
the world)."""


def yaw_of(rotation: np.ndarray) -> float:
    """Heading (rad, + left) of a rotation matrix's x axis in the horizontal plane."""
    return math.atan2(float(rotation[1, 0]), float(rotation[0, 0]))


def wrap(angle: float) -> float:
    """An angle (rad) wrapped to -pi..pi."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def place_crowd(rng: np.random.Generator, people: tuple[int, int]) -> tuple[scenes.RoomConfig, float, list[float]]:
    """Draw the room's layout: the wheelchair, ``people`` = (low, high) people (one calls) and
    the loudspeaker.

    Returns
    -------
    config : acoustic_sim.world.scenes.RoomConfig
    person_bearing_deg : float
        The caller's bearing from the wheelchair's heading (deg, + left).
    bystander_bearings_deg : list of float
        The silent people's bearings, in the order of :data:`acoustic_sim.world.names.BYSTANDERS`.

    Raises
    ------
    ConfigError
        If 100 draws found no layout that fits (a bug: the room has space for three).
    """
    n = int(rng.integers(people[0], people[1] + 1))
    for _ in range(100):  # a draw whose people or loudspeaker do not fit (walls, spacing) is drawn again
        chair = np.array([rng.uniform(1.5, ROOM_SIZE[0] - 1.5), rng.uniform(1.5, ROOM_SIZE[1] - 1.5)])
        heading = rng.uniform(-180.0, 180.0)
        spots: list[tuple[np.ndarray, float]] = []
        for _ in range(n):
            spot = place(rng, chair, heading, [b for _, b in spots])
            if spot is None:
                break
            spots.append(spot)
        if len(spots) < n:
            continue
        caller = int(rng.integers(n))
        person, person_bearing = spots.pop(caller)
        placed = place(rng, chair, heading, [person_bearing], speaker=True)
        if placed is not None:
            speaker = placed[0]
            break
    else:
        raise ConfigError(f"could not place {n} people and the loudspeaker in the room (this is a bug)")

    def face(p):  # facing the robot
        return math.degrees(math.atan2(chair[1] - p[1], chair[0] - p[0]))

    config = scenes.RoomConfig(wheelchair_position=tuple(chair), wheelchair_yaw_deg=float(heading),
                               person_position=tuple(person), person_yaw_deg=face(person),
                               speaker_position=tuple(speaker), speaker_yaw_deg=face(speaker),
                               bystanders=tuple((float(p[0]), float(p[1]), face(p)) for p, _ in spots))
    return config, float(person_bearing), [float(b) for _, b in spots]


def place(rng, chair, heading_deg, avoid_bearings, *, speaker: bool = False):
    """A floor point 0.6 m inside the walls at a random bearing (deg, relative to the
    wheelchair's heading) and distance, :data:`APART_DEG` from every bearing of
    ``avoid_bearings``; a person (not ``speaker``) out of view. None if none is found."""
    for _ in range(1000):
        bearing = rng.uniform(-180.0, 180.0)
        dist = rng.uniform(1.3, 2.5) if speaker else rng.uniform(1.4, 2.4)
        if not speaker and abs(bearing) < OUT_OF_VIEW_DEG:
            continue  # people start out of view
        if any(abs(wrap(math.radians(bearing - b))) < math.radians(APART_DEG) for b in avoid_bearings):
            continue
        a = math.radians(heading_deg + bearing)
        p = chair + dist * np.array([math.cos(a), math.sin(a)])
        if 0.6 <= p[0] <= ROOM_SIZE[0] - 0.6 and 0.6 <= p[1] <= ROOM_SIZE[1] - 0.6:
            return p, bearing
    return None


class Sight:
    """What the right eye camera sees of the people, geometrically, in one episode.

    Parameters
    ----------
    model, data
        The episode's MuJoCo model and data.
    view : acoustic_sim.world.view.WorldView
        The episode's view of them.
    image_size : tuple of int
        (height, width) of the eye image, pixels: the horizontal field of view (the
        vertical one is the eye cameras' 60 deg).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, view, image_size: tuple[int, int]) -> None:
        self.model, self.data, self.view = model, data, view
        h, w = image_size
        self._tan_v = math.tan(math.radians(60.0) / 2.0)  # the eye cameras' fovy
        self._tan_h = self._tan_v * w / h
        self._gaze_prev: np.ndarray | None = None
        self.gaze_speed_deg_s = 0.0
        """The gaze's angular speed (deg/s) over the last step (:meth:`update_gaze_speed`)."""

    def person_in_view(self, head_body: str = names.PERSON_HEAD_BODY) -> tuple[bool, tuple[float, float]]:
        """Whether a person's head (default the caller's) is in the right eye camera's field of
        view and not occluded, and where (normalized image coordinates u right, v up, -1..1)."""
        origin, rot = self.view.camera_pose(names.EYE_CAMERAS[1])
        head = self.view.body_pose(head_body)[0]
        d = head - origin
        c = rot.T @ d  # camera frame: x right, y up, looking along -z
        if c[2] >= -1e-6:
            return False, (0.0, 0.0)
        u, v = c[0] / (-c[2]) / self._tan_h, c[1] / (-c[2]) / self._tan_v
        if abs(u) > 1.0 or abs(v) > 1.0:
            return False, (0.0, 0.0)
        return self._unoccluded(origin, head, head_body[: head_body.index("/") + 1]), (float(u), float(v))

    def _unoccluded(self, origin: np.ndarray, target: np.ndarray, prefix: str) -> bool:
        m = self.model
        direction = target - origin
        dist = float(np.linalg.norm(direction))
        direction = direction / dist
        start, travelled = origin.copy(), 0.0
        for _ in range(8):  # skip the robot's own head and eyes around the camera
            hit, geom = self.view.ray(start, direction)
            if hit < 0 or travelled + hit >= dist + 0.15:
                return False  # nothing on the way: the ray missed the head's geoms
            name = m.body(int(m.geom_bodyid[geom])).name
            if any(name.startswith(p) for p in (names.PERSON, *names.BYSTANDERS)):
                return name.startswith(prefix)  # a person: the one looked for, or another in the way
            if not name.startswith(names.ROBOT):
                return False
            travelled += hit + 1e-4
            start = origin + travelled * direction
        return False

    def update_gaze_speed(self, dt: float) -> None:
        """The right eye's forward axis's angular speed in the world (deg/s) over the last
        step of ``dt`` seconds."""
        forward = -self.view.camera_pose(names.EYE_CAMERAS[1])[1][:, 2]
        if self._gaze_prev is not None:
            c = float(np.clip(np.dot(forward, self._gaze_prev), -1.0, 1.0))
            self.gaze_speed_deg_s = math.degrees(math.acos(c)) / dt
        self._gaze_prev = forward


class Look:
    """The look rule of one episode: who is looked at, step by step, once the call is heard."""

    def __init__(self) -> None:
        self._look = (None, 0)  # (who, steps) of the look in progress
        self._before_call: set | None = None

    def update(self, visible: list[str], heard: bool, still: bool) -> tuple[str | None, int]:
        """One step: ``visible``, the people in view (``"caller"`` or a bystander's name);
        ``heard``, whether the call has started; ``still``, whether the gaze is still.
        Returns who is being looked at (None: nobody) and for how many steps in a row."""
        if heard:
            # Whoever is in view when the call starts was not turned to: they count once the
            # gaze has left them and come back.
            self._before_call = set(visible) if self._before_call is None else self._before_call & set(visible)
        who = None
        if heard and still:
            who = next((v for v in visible if v not in self._before_call), None)
        steps = self._look[1] + 1 if who is not None and who == self._look[0] else (1 if who else 0)
        self._look = (who, steps)
        return self._look


__all__ = ["APART_DEG", "LOOK_S", "OUT_OF_VIEW_DEG", "ROOM_SIZE", "STILL_DEG_S", "Look", "Sight", "place", "place_crowd",
           "wrap", "yaw_of"]
