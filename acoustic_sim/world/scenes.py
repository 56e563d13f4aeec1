"""Composed MuJoCo scenes: the robot in the car's driver's seat, and on a wheelchair in a room.

Scenes are built in code with :class:`mujoco.MjSpec` from the menagerie-style assets under
``assets/`` (mjlab style): each asset is parsed from its ``<object>.xml`` and attached with
``MjSpec.attach(child, prefix=..., frame=... | site=...)``, so every element gets the full
name :mod:`acoustic_sim.world.names` promises (``robot/ear_left``, ``car/gearshift``, ...).
No XML string is edited.

``cabin``
    ``car_cabin`` attached at the world origin (the cabin frame is the acoustic room's
    frame), the robot (``musashi_head``) at the driver's hip point ``car/driver_seat``, its
    shins angled forward to the pedals. Two ball-joint (``connect``) equalities, inactive,
    let the hands hold the levers: ``robot/left_grasp`` (left hand - gearshift) and
    ``robot/right_grasp`` (right hand - brake), switched by :func:`grasp` and :func:`release`.
``room``
    ``wheelchair/room.xml`` (a 6 x 5 x 3 m room) as the base, the wheelchair on its floor,
    the robot on its seat, a person and a loudspeaker (both mocap bodies, placed with
    :func:`place_mocap`).

The acoustic room of a scene is derived from its box-typed air-volume site by
:func:`acoustic_room` (corner at the box's -x, -y, -z extreme, axes the box's), with the
materials of the matching preset of :mod:`acoustic_sim.acoustics.room`, so the MuJoCo
geometry and the acoustics never disagree (:mod:`acoustic_sim.world.scene_room`). Acting on
a scene (:func:`grasp`, :func:`release`, :func:`is_grasping`, :func:`reach`,
:func:`place_mocap`) is :mod:`acoustic_sim.world.actuation`'s; both are re-exported here.

Mechanisms are pure MJCF physics and need no per-step Python: the gearshift's detents are a
spring-loaded roller between bumps, the brake's ratchet a sprung pawl over pins (see
``assets/car_cabin/README.md``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np

from acoustic_sim.acoustics.room import Room
from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names
from acoustic_sim.world.actuation import grasp, home_pose, is_grasping, place_mocap, reach, release, yaw_quaternion
from acoustic_sim.world.scene_room import ROOM_PRESETS, acoustic_room, room_frame, to_room

ASSET_DIR = Path(__file__).resolve().parents[2] / "assets"
"""The repository's ``assets/`` folder (one menagerie-style folder per object)."""

SCENES = ("cabin", "room")
"""Names accepted by :func:`build_scene` and :func:`load_scene`."""

TIMESTEP = 0.002
"""Physics timestep (s): 8 steps per 16 ms control step."""

DRIVING_KNEE_DEG = -55.0
"""Rotation (deg, about the thigh's y axis) of the shins in the driver's seat: feet forward
on the pedals instead of straight down."""


REVERSE_DEG_RANGE = (7.0, 23.0)
"""Range (deg) of :attr:`CabinConfig.reverse_deg`: R at least 7 deg from P (0) and from N (30)."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class CabinConfig:
    """Initial state of the ``cabin`` scene."""

    gear: str = "P"
    """Gear the lever starts in: one of ``names.GEAR_NAMES`` (P, R, N, D)."""

    brake_tooth: int = 0
    """Ratchet tooth the parking brake starts on: 0 = fully down, 1..7 = held on that tooth."""

    reverse_deg: float = 15.0
    """Lever angle (deg, 7..23) of the R detent: where this car's R is, between P (0 deg) and
    N (30 deg). The two detent bumps around R move with it, symmetric about it, so the gate's
    feel moves too; the asset's own R is at 15 deg."""

    def __post_init__(self) -> None:
        if self.gear not in names.GEAR_NAMES:
            raise ConfigError(f"CabinConfig.gear must be one of {names.GEAR_NAMES}, got {self.gear!r}")
        lo, hi = REVERSE_DEG_RANGE
        if not (isinstance(self.reverse_deg, (int, float, np.integer, np.floating)) and lo <= self.reverse_deg <= hi):
            raise ConfigError(f"CabinConfig.reverse_deg must be {lo:g}..{hi:g} deg (between P and N), got {self.reverse_deg!r}")
        n = len(names.BRAKE_TOOTH_ANGLES_DEG)
        if not isinstance(self.brake_tooth, (int, np.integer)) or not 0 <= self.brake_tooth <= n:
            raise ConfigError(f"CabinConfig.brake_tooth must be an integer 0..{n}, got {self.brake_tooth!r}")


@dataclasses.dataclass(frozen=True, kw_only=True)
class RoomConfig:
    """Where things stand in the ``room`` scene (room frame: origin at a floor corner, metres)."""

    wheelchair_position: tuple[float, float] = (2.0, 2.5)
    """Floor point (x, y) midway between the wheelchair's drive wheels, m."""

    wheelchair_yaw_deg: float = 0.0
    """Heading of the wheelchair (and the robot), deg counter-clockwise from +x."""

    person_position: tuple[float, float] = (4.0, 2.9)
    """Floor point (x, y) between the person's feet, m."""

    person_yaw_deg: float = -170.0
    """Direction the person faces, deg counter-clockwise from +x."""

    speaker_position: tuple[float, float] = (3.5, 1.2)
    """Floor point (x, y) of the loudspeaker stand, m."""

    speaker_yaw_deg: float = 140.0
    """Direction the loudspeaker faces, deg counter-clockwise from +x."""

    bystanders: tuple = ()
    """Other people in the room (at most ``len(names.BYSTANDERS)``, 2), each ``(x, y, yaw_deg)``:
    floor point (m) and facing direction like the person's; silent (no emitter)."""

    def __post_init__(self) -> None:
        for field in ("wheelchair_position", "person_position", "speaker_position"):
            xy = np.asarray(getattr(self, field), dtype=float)
            if xy.shape != (2,) or not np.all(np.isfinite(xy)):
                raise ConfigError(f"RoomConfig.{field} must be 2 finite coordinates (x, y) in m, got {getattr(self, field)!r}")
        for field in ("wheelchair_yaw_deg", "person_yaw_deg", "speaker_yaw_deg"):
            if not np.isfinite(getattr(self, field)):
                raise ConfigError(f"RoomConfig.{field} must be a finite angle in degrees, got {getattr(self, field)!r}")
        try:
            others = np.asarray(self.bystanders, dtype=float).reshape(-1, 3)
        except (TypeError, ValueError):
            others = None
        if (others is None or len(others) != len(self.bystanders) or len(others) > len(names.BYSTANDERS)
                or not np.all(np.isfinite(others))):
            raise ConfigError(f"RoomConfig.bystanders must be at most {len(names.BYSTANDERS)} finite (x, y, yaw_deg) "
                              f"triples, got {self.bystanders!r}")


@dataclasses.dataclass(frozen=True)
class SceneInfo:
    """What :func:`load_scene` knows about the scene besides the model and data.

    Attributes
    ----------
    name : str
        ``cabin`` or ``room``.
    config : CabinConfig or RoomConfig
        The configuration the scene was built with.
    room : acoustic_sim.acoustics.room.Room
        The acoustic room derived from the scene's air-volume site (:func:`acoustic_room`).
    """

    name: str
    config: CabinConfig | RoomConfig
    room: Room


# -- building --------------------------------------------------------------------------------------


def _asset(folder: str, file: str) -> mujoco.MjSpec:
    """Parse one asset file; mesh paths are made absolute so they survive attachment."""
    path = ASSET_DIR / folder / file
    if not path.is_file():
        raise ConfigError(f"asset file {path} is missing (is this a complete checkout?)")
    spec = mujoco.MjSpec.from_file(str(path))
    mesh_dir = path.parent / spec.meshdir
    for mesh in spec.meshes:
        if mesh.file:
            mesh.file = str((mesh_dir / mesh.file).resolve())
    spec.meshdir = ""
    return spec


def _set_physics(spec: mujoco.MjSpec) -> None:
    spec.option.timestep = TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def _cabin_world() -> mujoco.MjSpec:
    """Empty world with physics options, sky, road and sun for the cabin scene."""
    spec = mujoco.MjSpec()
    spec.modelname = "cabin"
    _set_physics(spec)
    spec.stat.center = [1.0, 0.9, 0.5]
    spec.stat.extent = 2.5
    spec.visual.headlight.diffuse = [0.6, 0.6, 0.6]
    spec.visual.headlight.ambient = [0.3, 0.3, 0.3]
    spec.visual.headlight.specular = [0.0, 0.0, 0.0]
    spec.add_texture(name="skybox", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     rgb1=[0.3, 0.5, 0.7], rgb2=[0.0, 0.0, 0.0], width=512, height=3072)
    spec.add_texture(name="road", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                     mark=mujoco.mjtMark.mjMARK_EDGE, rgb1=[0.25, 0.25, 0.27], rgb2=[0.2, 0.2, 0.22],
                     markrgb=[0.6, 0.6, 0.6], width=300, height=300)
    road = spec.add_material(name="road", texrepeat=[4, 4], texuniform=True, reflectance=0.1)
    road.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "road"
    spec.worldbody.add_geom(name="road", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], pos=[1.0, 0.75, -0.25],
                            material="road", contype=0, conaffinity=0)
    spec.worldbody.add_light(name="sun", pos=[1.0, 0.75, 4.0], dir=[0.0, 0.0, -1.0], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                             diffuse=[0.6, 0.6, 0.6], castshadow=False)
    return spec


def _build_cabin(config: CabinConfig) -> mujoco.MjSpec:
    spec = _cabin_world()
    spec.attach(_asset("car_cabin", "car_cabin.xml"), prefix=names.CAR, frame=spec.worldbody.add_frame())
    _place_reverse(spec, config.reverse_deg)
    spec.attach(_asset("musashi_head", "musashi_head.xml"), prefix=names.ROBOT, site=spec.site(names.CABIN_SEAT_SITE))
    for side in names.ARM_SIDES:
        half = np.deg2rad(DRIVING_KNEE_DEG) / 2.0
        spec.body(f"{names.ROBOT}{side}_shin").quat = [float(np.cos(half)), 0.0, float(np.sin(half)), 0.0]
        # A ball-joint grip (connect), not a weld: a weld's 6 constraints on a 5-joint arm
        # holding a 1-joint lever would leave no motion at all.
        spec.add_equality(
            name=names.grasp_equality(side), type=mujoco.mjtEq.mjEQ_CONNECT, objtype=mujoco.mjtObj.mjOBJ_BODY,
            name1=names.hand_body(side), name2=names.GRASP_TARGET_BODIES[side], active=False,
            solref=[0.01, 1.0], solimp=[0.95, 0.99, 0.001, 0.5, 2.0],
        )
    return spec


GEAR_BUMP_FRAME_OFFSET_DEG = 22.5
"""A bump at frame angle b (deg, about the lever body's y axis) is under the detent roller at
lever angle b + 22.5 deg (the lever body's own tilt in the asset)."""


def _place_reverse(spec: mujoco.MjSpec, reverse_deg: float) -> None:
    """Put the R detent at ``reverse_deg``: the detent angles' numeric, and the two bumps
    around R (the asset's P, N and D detents stay where they are)."""
    numeric = spec.numeric(names.GEAR_DETENTS_NUMERIC)
    detents = [float(v) for v in numeric.data]
    r = names.GEAR_NAMES.index("R")
    p, n = np.rad2deg(detents[r - 1]), np.rad2deg(detents[r + 1])
    if reverse_deg == round(float(np.rad2deg(detents[r])), 4):
        return  # the asset's own R: leave the spec as the asset wrote it
    detents[r] = float(np.deg2rad(reverse_deg))
    numeric.data = detents
    # Symmetric about R (its valley's bottom, where the roller rests, is R itself), half the
    # way to the nearer of P and N.
    w = min(reverse_deg - p, n - reverse_deg) / 2.0
    for frame, between in (("gear_bump_pr", reverse_deg - w), ("gear_bump_rn", reverse_deg + w)):
        spec.frame(names.CAR + frame).alt.euler = [0.0, between - GEAR_BUMP_FRAME_OFFSET_DEG, 0.0]


def _check_floor_point(room: mujoco.MjsSite, what: str, xy) -> None:
    centre, half = np.asarray(room.pos[:2]), np.asarray(room.size[:2])
    lo, hi = centre - half + 0.3, centre + half - 0.3
    p = np.asarray(xy, dtype=float)
    if np.any(p < lo) or np.any(p > hi):
        raise ConfigError(f"RoomConfig.{what} {tuple(p)} must be at least 0.3 m inside the room walls: x {lo[0]:g}..{hi[0]:g}, "
                          f"y {lo[1]:g}..{hi[1]:g} m")


def _build_room(config: RoomConfig) -> mujoco.MjSpec:
    spec = _asset("wheelchair", "room.xml")
    spec.modelname = "room"
    _set_physics(spec)
    interior = spec.site(names.ROOM_INTERIOR_SITE)
    placements = (
        ("wheelchair_position", config.wheelchair_position, config.wheelchair_yaw_deg, "wheelchair", "wheelchair.xml", names.WHEELCHAIR),
        ("person_position", config.person_position, config.person_yaw_deg, "person", "person.xml", names.PERSON),
        ("speaker_position", config.speaker_position, config.speaker_yaw_deg, "loudspeaker", "loudspeaker.xml", names.SPEAKER),
    )
    placements += tuple((f"bystanders[{i}]", b[:2], b[2], "person", "person.xml", names.BYSTANDERS[i])
                        for i, b in enumerate(config.bystanders))
    for field, xy, yaw, folder, file, prefix in placements:
        _check_floor_point(interior, field, xy)
        frame = spec.worldbody.add_frame(pos=[float(xy[0]), float(xy[1]), 0.0], quat=yaw_quaternion(yaw))
        spec.attach(_asset(folder, file), prefix=prefix, frame=frame)
    spec.attach(_asset("musashi_head", "musashi_head.xml"), prefix=names.ROBOT, site=spec.site(names.WHEELCHAIR_SEAT_SITE))
    return spec


def build_scene(name: str, *, config: CabinConfig | RoomConfig | None = None) -> mujoco.MjSpec:
    """Compose a scene as an editable :class:`mujoco.MjSpec` (compile it with ``spec.compile()``).

    Parameters
    ----------
    name : str
        One of :data:`SCENES`: ``cabin`` or ``room``.
    config : CabinConfig or RoomConfig, optional
        The scene's configuration (default: the dataclass defaults); it must match ``name``.
        The room's placements are built into the spec (the wheelchair's free joint and the
        mocap bodies start there); the cabin's lever positions are a state, which
        :func:`load_scene` applies.

    Raises
    ------
    ConfigError
        For an unknown scene name, a config of the wrong type, or a placement outside the room.
    """
    if name not in SCENES:
        raise ConfigError(f"unknown scene {name!r}; valid scenes: {', '.join(SCENES)}")
    expected = CabinConfig if name == "cabin" else RoomConfig
    config = expected() if config is None else config
    if not isinstance(config, expected):
        raise ConfigError(f"scene {name!r} takes a {expected.__name__}, got {type(config).__name__}")
    return _build_cabin(config) if name == "cabin" else _build_room(config)


def _numeric(model: mujoco.MjModel, name: str) -> np.ndarray:
    n = model.numeric(name)
    return np.array(model.numeric_data[n.adr[0] : n.adr[0] + n.size[0]])


def load_scene(name: str, *, config: CabinConfig | RoomConfig | None = None) -> tuple[mujoco.MjModel, mujoco.MjData, SceneInfo]:
    """Build and compile a scene, and put it in its initial state.

    The robot starts in its seated rest pose (the asset's ``home`` keyframe, position targets
    equal to it), the cabin's levers as ``config`` says; then ``mj_forward`` runs, so every
    derived quantity is valid.

    Parameters
    ----------
    name : str
        ``cabin`` or ``room``.
    config : CabinConfig or RoomConfig, optional

    Returns
    -------
    model : mujoco.MjModel
    data : mujoco.MjData
    info : SceneInfo
        Name, configuration and the acoustic room of the scene.
    """
    spec = build_scene(name, config=config)
    model = spec.compile()
    data = mujoco.MjData(model)
    used = config or (CabinConfig() if name == "cabin" else RoomConfig())
    levers = {}
    if name == "cabin":
        # The asset's own numerics say where the detents and teeth are.
        levers[names.GEARSHIFT_JOINT] = _numeric(model, names.GEAR_DETENTS_NUMERIC)[names.GEAR_NAMES.index(used.gear)]
        if used.brake_tooth:
            levers[names.BRAKE_JOINT] = _numeric(model, names.BRAKE_TEETH_NUMERIC)[used.brake_tooth - 1]
    home_pose(model, data, levers)
    return model, data, SceneInfo(name=name, config=used, room=acoustic_room(model))


__all__ = [
    "ASSET_DIR", "DRIVING_KNEE_DEG", "GEAR_BUMP_FRAME_OFFSET_DEG", "REVERSE_DEG_RANGE", "ROOM_PRESETS", "SCENES", "TIMESTEP",
    "CabinConfig", "RoomConfig", "SceneInfo", "acoustic_room", "build_scene", "grasp", "is_grasping", "load_scene",
    "place_mocap", "reach", "release", "room_frame", "to_room",
]
