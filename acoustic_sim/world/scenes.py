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
geometry and the acoustics never disagree.

Mechanisms are pure MJCF physics and need no per-step Python: the gearshift's detents are a
spring-loaded roller between bumps, the brake's ratchet a sprung pawl over pins (see
``assets/car_cabin/README.md``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np

from acoustic_sim.acoustics.room import WALLS, Room, eyring_absorption, room_preset
from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names
from acoustic_sim.world.room_box import RoomFrame

ASSET_DIR = Path(__file__).resolve().parents[2] / "assets"
"""The repository's ``assets/`` folder (one menagerie-style folder per object)."""

SCENES = ("cabin", "room")
"""Names accepted by :func:`build_scene` and :func:`load_scene`."""

TIMESTEP = 0.002
"""Physics timestep (s): 8 steps per 16 ms control step."""

ROOM_PRESETS = {names.CABIN_INTERIOR_SITE: "car_cabin", names.ROOM_INTERIOR_SITE: "lab"}
"""Acoustic preset whose materials each air-volume site takes (acoustics.room.room_preset)."""

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


def _yaw_quat(yaw_deg: float) -> list[float]:
    half = np.deg2rad(yaw_deg) / 2.0
    return [float(np.cos(half)), 0.0, 0.0, float(np.sin(half))]


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
        frame = spec.worldbody.add_frame(pos=[float(xy[0]), float(xy[1]), 0.0], quat=_yaw_quat(yaw))
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
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, names.ROBOT + "home")
    # Only the robot's coordinates and controls come from its keyframe: everything else keeps
    # its reference pose (the wheelchair where it was placed) and the mocap bodies stay put.
    robot_joints = [j for j in range(model.njnt) if (model.joint(j).name or "").startswith(names.ROBOT)]
    for j in robot_joints:
        adr = model.jnt_qposadr[j]
        data.qpos[adr] = model.key_qpos[key, adr]
    robot_actuators = [a for a in range(model.nu) if (model.actuator(a).name or "").startswith(names.ROBOT)]
    data.ctrl[robot_actuators] = model.key_ctrl[key, robot_actuators]
    used = config or (CabinConfig() if name == "cabin" else RoomConfig())
    if name == "cabin":
        # The asset's own numerics say where the detents and teeth are.
        data.joint(names.GEARSHIFT_JOINT).qpos[0] = _numeric(model, names.GEAR_DETENTS_NUMERIC)[names.GEAR_NAMES.index(used.gear)]
        if used.brake_tooth:
            data.joint(names.BRAKE_JOINT).qpos[0] = _numeric(model, names.BRAKE_TEETH_NUMERIC)[used.brake_tooth - 1]
    mujoco.mj_forward(model, data)
    return model, data, SceneInfo(name=name, config=used, room=acoustic_room(model))


# -- the acoustic room ----------------------------------------------------------------------------


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
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    if sid < 0:
        raise ConfigError(f"the model has no site {site!r}")
    if int(model.site_type[sid]) != int(mujoco.mjtGeom.mjGEOM_BOX):
        raise ConfigError(f"site {site!r} must be box-typed (it describes an air volume)")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return RoomFrame.from_box(data.site_xpos[sid], data.site_xmat[sid].reshape(3, 3), model.site_size[sid])


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
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    try:
        ears = np.stack([data.site(names.EAR_LEFT_SITE).xpos, data.site(names.EAR_RIGHT_SITE).xpos])
    except KeyError:
        raise ConfigError(f"the model has no robot ear sites {names.EAR_LEFT_SITE!r}, {names.EAR_RIGHT_SITE!r}") from None
    listener = to_room(model, ears.mean(axis=0), site)
    absorption = preset.absorption
    if preset.target_rt60_s is not None:
        a = eyring_absorption(preset.target_rt60_s, dims)
        absorption = {w: (a,) for w in WALLS}
    return dataclasses.replace(preset, dimensions=tuple(float(v) for v in dims), absorption=absorption,
                               listener=tuple(float(v) for v in listener))


# -- acting on the scene ---------------------------------------------------------------------------


def _side(side: str) -> str:
    if side not in names.ARM_SIDES:
        raise ConfigError(f"side must be one of {names.ARM_SIDES}, got {side!r}")
    return side


def _grasp_id(model: mujoco.MjModel, side: str) -> int:
    eq = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_EQUALITY, names.grasp_equality(_side(side)))
    if eq < 0:
        raise ConfigError(f"this scene has no grasp {names.grasp_equality(side)!r} (only the cabin has levers to hold)")
    return eq


def grasp(model: mujoco.MjModel, data: mujoco.MjData, side: str, *, max_distance: float = 0.05) -> bool:
    """Close a hand on its lever: pin the palm to the point of the lever where it is now.

    The grip is a ball joint (a ``connect`` equality) between the palm site and the lever,
    anchored where the palm is, so grasping moves nothing; from then on the lever's handle
    follows the palm (and resists it through its detents or ratchet) while turning freely
    in the hand, as a gear knob turns in a loose fist.

    Parameters
    ----------
    side : str
        ``left`` (gearshift) or ``right`` (brake lever).
    max_distance : float
        The palm site must be this close (m) to the lever's handle site, > 0.

    Returns
    -------
    bool
        True if the hand now holds the lever; False if the handle was out of reach.

    Raises
    ------
    ConfigError
        If the scene has no such grasp (only ``cabin`` has) or ``side`` is unknown.
    """
    eq = _grasp_id(model, side)
    if not max_distance > 0:
        raise ConfigError(f"max_distance must be > 0 m, got {max_distance}")
    mujoco.mj_kinematics(model, data)
    palm_site = data.site(names.grasp_site(side))
    handle = data.site(names.GRASP_TARGET_SITES[side]).xpos
    if np.linalg.norm(palm_site.xpos - handle) > max_distance:
        return False
    hand, lever = int(model.eq_obj1id[eq]), int(model.eq_obj2id[eq])
    palm = palm_site.xpos.copy()
    # Connect data: the anchor in body1's frame, then the same point in body2's frame.
    model.eq_data[eq, 0:3] = data.xmat[hand].reshape(3, 3).T @ (palm - data.xpos[hand])
    model.eq_data[eq, 3:6] = data.xmat[lever].reshape(3, 3).T @ (palm - data.xpos[lever])
    data.eq_active[eq] = 1
    return True


def release(model: mujoco.MjModel, data: mujoco.MjData, side: str) -> None:
    """Open a hand: deactivate its grasp equality (a no-op when it holds nothing)."""
    data.eq_active[_grasp_id(model, side)] = 0


def is_grasping(model: mujoco.MjModel, data: mujoco.MjData, side: str) -> bool:
    """Whether the hand on ``side`` holds its lever."""
    return bool(data.eq_active[_grasp_id(model, side)])


def reach(model: mujoco.MjModel, data: mujoco.MjData, side: str, target, *, max_error: float = 0.01,
          iterations: int = 200) -> np.ndarray:
    """Arm joint angles (rad) that put the palm site at ``target``: position inverse kinematics.

    Damped least squares from the arm's current pose over the five joints of
    :func:`names.arm_joints`, within their ranges; ``data`` is not changed. Use the result as
    the arm's position targets (``ctrl``).

    Parameters
    ----------
    side : str
        ``left`` or ``right``.
    target : array_like, shape (3,)
        Palm position (m, world).
    max_error : float
        Largest acceptable distance (m) between the palm and the target.
    iterations : int
        Most solver iterations.

    Returns
    -------
    numpy.ndarray, shape (5,)
        Shoulder pitch, roll, yaw, elbow, wrist (rad).

    Raises
    ------
    ConfigError
        If the target is not 3 finite numbers or is out of reach (error above ``max_error``).
    """
    target = np.asarray(target, dtype=float)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise ConfigError(f"reach target must be 3 finite coordinates in m, got {target!r}")
    joints = [model.joint(j) for j in names.arm_joints(_side(side))]
    qadr = np.array([j.qposadr[0] for j in joints])
    dadr = np.array([j.dofadr[0] for j in joints])
    lo, hi = np.array([j.range for j in joints]).T
    site = model.site(names.grasp_site(side)).id
    scratch = mujoco.MjData(model)
    scratch.qpos[:] = data.qpos
    scratch.mocap_pos[:], scratch.mocap_quat[:] = data.mocap_pos, data.mocap_quat
    jac = np.zeros((3, model.nv))
    damping = 1e-2
    for _ in range(iterations):
        mujoco.mj_kinematics(model, scratch)
        mujoco.mj_comPos(model, scratch)
        err = target - scratch.site_xpos[site]
        if np.linalg.norm(err) < 1e-4:
            break
        mujoco.mj_jacSite(model, scratch, jac, None, site)
        j = jac[:, dadr]
        dq = j.T @ np.linalg.solve(j @ j.T + damping**2 * np.eye(3), err)
        scratch.qpos[qadr] = np.clip(scratch.qpos[qadr] + dq, lo, hi)
    mujoco.mj_kinematics(model, scratch)
    error = float(np.linalg.norm(target - scratch.site_xpos[site]))
    if error > max_error:
        raise ConfigError(f"{side} palm cannot reach {tuple(np.round(target, 3))} m: {error * 100:.1f} cm short")
    return scratch.qpos[qadr].copy()


def place_mocap(model: mujoco.MjModel, data: mujoco.MjData, body: str, position, yaw_deg: float = 0.0) -> None:
    """Move a mocap body (the person, the loudspeaker) to a floor point, facing ``yaw_deg``.

    Parameters
    ----------
    body : str
        Full body name, e.g. ``names.PERSON_ROOT_BODY`` or ``names.LOUDSPEAKER_BODY``.
    position : array_like, shape (3,)
        Body origin (m, world): for both, the floor point under them.
    yaw_deg : float
        Facing direction, deg counter-clockwise from +x.

    Raises
    ------
    ConfigError
        If the body does not exist or is not a mocap body, or the pose is not finite.
    """
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    if bid < 0 or model.body_mocapid[bid] < 0:
        raise ConfigError(f"{body!r} is not a mocap body of this scene")
    p = np.asarray(position, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)) or not np.isfinite(yaw_deg):
        raise ConfigError(f"mocap pose must be 3 finite coordinates (m) and a finite yaw (deg), got {position!r}, {yaw_deg!r}")
    m = model.body_mocapid[bid]
    data.mocap_pos[m] = p
    data.mocap_quat[m] = _yaw_quat(yaw_deg)
