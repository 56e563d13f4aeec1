"""The scene of an ``eval active`` trial: sounds from around a head that turns once, and
the pipeline hearing it block by block.

A trial's sounds start :data:`LEAD_S` into the recording, :data:`DISTANCE_M` from the head
(nearer where a wall is closer), at a level drawn from :data:`LEVEL_DB_SPL`; the head faces
the room's +x and, :data:`TURN_START_S` after the sound starts, turns about the vertical at
:data:`TURN_SPEED_DEG_S`, then holds. :func:`render_scene` gives the ear signals and the
head's pose per control block; :func:`listen` feeds them to the pipeline in the same blocks.
Shared by the single-source trials (:mod:`~acoustic_sim.experiments.active`) and the
two-source scenes (:mod:`~acoustic_sim.experiments.active_pairs`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory.pipeline import AuditoryPipeline
from acoustic_sim.frames import SAMPLE_RATE, rotation_zyx

DISTANCE_M = {"lab": 1.5, "car_cabin": 0.8, "anechoic": 1.5}
"""Source distance per room (m); a source is brought nearer where a wall is closer than
:data:`WALL_CLEARANCE_M` beyond it."""

WALL_CLEARANCE_M = 0.05
"""Least distance (m) between a source and the room's walls."""

TURN_SPEED_DEG_S = 90.0
"""Speed of the head turn (deg/s): a 30 deg turn takes a third of a second."""

TURN_START_S = 0.25
"""When the turn starts, after the sound's start (s)."""

SOUND_S = 1.5
"""Length of each sound (s)."""

LEAD_S = 0.1
"""Room background before the sound starts (s)."""

LEVEL_DB_SPL = (73.0, 76.0)
"""The sound's level at the head (dB SPL), drawn per trial as in the paper's room experiment."""


def source_distance(space, head: np.ndarray, direction: np.ndarray, distance_m: float) -> float:
    """``distance_m``, or less so that the source stays :data:`WALL_CLEARANCE_M` inside the room."""
    if space.anechoic:
        return distance_m
    lo = np.zeros(3) + WALL_CLEARANCE_M
    hi = np.asarray(space.dimensions, float) - WALL_CLEARANCE_M
    reach = np.inf
    for i in range(3):
        if direction[i] > 1e-9:
            reach = min(reach, (hi[i] - head[i]) / direction[i])
        elif direction[i] < -1e-9:
            reach = min(reach, (lo[i] - head[i]) / direction[i])
    return float(min(distance_m, reach))


def head_yaw_deg(t_s: float, turn_deg: float, sign: float) -> float:
    """The head's yaw (deg) at ``t_s`` after the sound's start: still, a turn of
    ``sign * turn_deg`` from :data:`TURN_START_S` at :data:`TURN_SPEED_DEG_S`, then held."""
    moved = np.clip((t_s - TURN_START_S) * TURN_SPEED_DEG_S, 0.0, turn_deg)
    return float(sign * moved)


def render_trial(hrtf: HRTF, room: str, direction: np.ndarray, sound: str, turn_deg: float, sign: float,
                 rng: np.random.Generator) -> tuple[np.ndarray, list]:
    """Digital ear signals (2, n) of one trial and the head's poses: a list of
    ``(time_s, rotation)`` per control block (time from the recording's start)."""
    return render_scene(hrtf, room, [(sound, direction)], turn_deg, sign, rng)


def render_scene(hrtf: HRTF, room: str, sources, turn_deg: float, sign: float,
                 rng: np.random.Generator) -> tuple[np.ndarray, list]:
    """:func:`render_trial` with several ``(sound, world direction)`` sources at once, each at
    its own level drawn from :data:`LEVEL_DB_SPL`."""
    space = room_preset(room)
    head = np.asarray(space.listener, float)
    r = BinauralRenderer(hrtf, space, rng=rng)
    start = int(round(LEAD_S * SAMPLE_RATE))
    r.set_head_pose(head, rotation_zyx(0.0))
    for i, (sound, direction) in enumerate(sources):
        level = float(rng.uniform(*LEVEL_DB_SPL))
        dist = source_distance(space, head, direction, DISTANCE_M.get(room, 1.5))
        x = sounds.generate(sound, rng, seconds=SOUND_S)
        r.add_source(f"source{i}", x, head + dist * np.asarray(direction, float),
                     level_db=level + 20 * math.log10(dist), start=start)
    total = int(round((LEAD_S + SOUND_S) * SAMPLE_RATE))
    blocks, poses = [], []
    while r.sample < total:
        t = r.sample / SAMPLE_RATE
        rot = rotation_zyx(head_yaw_deg(t - LEAD_S, turn_deg, sign))
        r.set_head_pose(head, rot)
        poses.append((t, rot))
        blocks.append(r.render_block())  # one control block: the pose holds within it
    return Microphone(rng=rng)(np.concatenate(blocks, axis=1)), poses


def listen(pipe: AuditoryPipeline, audio: np.ndarray, poses) -> Iterator:
    """Hear ``audio`` (2, n) afresh: reset ``pipe``, then feed it one control block at a
    time, each after its head pose (``poses`` as :func:`render_scene` gives them); yields the
    percepts in order."""
    pipe.reset()
    at = 0
    for (t, rot), (t_next, _) in zip(poses, poses[1:] + [(audio.shape[1] / SAMPLE_RATE, None)]):
        pipe.note_pose(t, rot)
        end = int(round(t_next * SAMPLE_RATE))
        yield from pipe.process(audio[:, at:end])
        at = end
