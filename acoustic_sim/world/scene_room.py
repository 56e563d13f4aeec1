"""The acoustic room of a composed scene, derived from its box-typed air-volume site.

The room's frame is the box's (corner at the box's -x, -y, -z extreme, axes the box's:
:class:`~acoustic_sim.world.room_box.RoomFrame`), its materials those of the matching preset
of :mod:`acoustic_sim.acoustics.room` (:data:`ROOM_PRESETS`), so the MuJoCo geometry and the
acoustics never disagree. Everything is read at the model's reference pose (``qpos0``),
where the scene placed it.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from acoustic_sim.acoustics.room import WALLS, Room, eyring_absorption, room_preset
from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names
from acoustic_sim.world.actuation import reference_pose
from acoustic_sim.world.room_box import RoomFrame
from acoustic_sim.world.view import SceneView

ROOM_PRESETS = {names.CABIN_INTERIOR_SITE: "car_cabin", names.ROOM_INTERIOR_SITE: "lab"}
"""Acoustic preset whose materials each air-volume site takes (acoustics.room.room_preset)."""


def _interior_site(model: mujoco.MjModel) -> str:
    for site in ROOM_PRESETS:
        if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site) >= 0:
            return site
    raise ConfigError(f"the model has no air-volume site ({' or '.join(map(repr, ROOM_PRESETS))}): not a composed scene")


def room_frame(model: mujoco.MjModel, site: str | None = None) -> RoomFrame:
    """The :class:`~acoustic_sim.world.room_box.RoomFrame` of the air volume (the box site's
    (-x, -y, -z) corner, the box's axes), as the coupling has it. The site is read at the
    model's reference pose (``qpos0``), where it is wherever the scene placed it.

    Raises
    ------
    ConfigError
        If the site is missing or not box-typed.
    """
    site = _interior_site(model) if site is None else site
    return RoomFrame.from_box(*SceneView(model, reference_pose(model)).site_box(site))


def to_room(model: mujoco.MjModel, points_world, site: str | None = None) -> np.ndarray:
    """Express world points (..., 3) in the acoustic room's frame (m)."""
    return room_frame(model, site).to_room(points_world)


def acoustic_room(model: mujoco.MjModel) -> Room:
    """The acoustic :class:`~acoustic_sim.acoustics.room.Room` of a composed scene.

    Dimensions come from the scene's box-typed air-volume site (``car/interior`` or
    ``room_interior``); materials, background noise and image-source order from the matching
    preset of :data:`ROOM_PRESETS` (``car_cabin``: its wall materials; ``lab``: the uniform
    absorption that gives the preset's RT60 in this volume, by Eyring's formula); the
    listener is the midpoint of the robot's ear sites at the reference pose, in room
    coordinates.

    Raises
    ------
    ConfigError
        If the model has no air-volume site or no robot ear sites, or the head is outside
        the air volume.
    """
    site = _interior_site(model)
    preset = room_preset(ROOM_PRESETS[site])
    dims = room_frame(model, site).dimensions
    at_rest = SceneView(model, reference_pose(model))
    if not (at_rest.has_site(names.EAR_LEFT_SITE) and at_rest.has_site(names.EAR_RIGHT_SITE)):
        raise ConfigError(f"the model has no robot ear sites {names.EAR_LEFT_SITE!r}, {names.EAR_RIGHT_SITE!r}")
    ears = np.stack([at_rest.site_position(names.EAR_LEFT_SITE), at_rest.site_position(names.EAR_RIGHT_SITE)])
    listener = to_room(model, ears.mean(axis=0), site)
    absorption = preset.absorption
    if preset.target_rt60_s is not None:
        a = eyring_absorption(preset.target_rt60_s, dims)
        absorption = {w: (a,) for w in WALLS}
    return dataclasses.replace(preset, dimensions=tuple(float(v) for v in dims), absorption=absorption,
                               listener=tuple(float(v) for v in listener))


__all__ = ["ROOM_PRESETS", "acoustic_room", "room_frame", "to_room"]
