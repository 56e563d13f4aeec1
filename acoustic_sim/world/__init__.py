"""The MuJoCo embodiment: composed scenes, the read-only view, sound events, the coupling.

Modules
-------
names
    The full names of the MuJoCo elements the code relies on (the assets' contract).
scenes, scene_room
    Scenes composed with ``mujoco.MjSpec`` from ``assets/``: :func:`build_scene`,
    :func:`load_scene`; the acoustic room of a scene (:func:`acoustic_room`, :func:`room_frame`).
actuation
    The one writer of ``MjData``: physics steps, the home pose, joints and servos, the hands
    (:func:`grasp`, :func:`release`, :func:`reach`), the mocap bodies (:func:`place_mocap`).
snapshot
    A PNG of a scene from MuJoCo's offscreen renderer.
view, lever_geometry, events, coupling, emitter_rings, egonoise
    Named read-only accessors over ``MjData`` (the one reader); the levers' detents and
    ratchet; sound events from physics; the once-per-control-step hand-off to the acoustic
    world and the ring buffers through which the emitters' sounds reach the renderer; the
    motors' ego-noise.
soundscape
    Sounds scheduled anywhere in the room (the one owner of their renderer sources) and the
    ground truth of what is sounding; :class:`acoustic_sim.loop.HearingLoop` drives it.

Nothing is imported here eagerly: MuJoCo picks its OpenGL backend (``MUJOCO_GL``) when it is
first imported, and :mod:`acoustic_sim.world.snapshot` must be able to choose it first. The
scene functions are re-exported lazily (``from acoustic_sim.world import load_scene``); the
snapshot is ``from acoustic_sim.world.snapshot import snapshot``.
"""

from __future__ import annotations

import importlib

_LAZY = {
    **{name: "acoustic_sim.world.scenes" for name in ("SCENES", "CabinConfig", "RoomConfig", "SceneInfo", "build_scene",
                                                      "load_scene")},
    **{name: "acoustic_sim.world.scene_room" for name in ("acoustic_room", "room_frame", "to_room")},
    **{name: "acoustic_sim.world.actuation" for name in ("grasp", "release", "is_grasping", "reach", "place_mocap")},
}

__all__ = [
    "SCENES",
    "CabinConfig",
    "RoomConfig",
    "SceneInfo",
    "acoustic_room",
    "build_scene",
    "grasp",
    "is_grasping",
    "load_scene",
    "place_mocap",
    "reach",
    "release",
    "room_frame",
    "to_room",
]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'acoustic_sim.world' has no attribute {name!r}")
