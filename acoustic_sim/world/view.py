"""A read-only, named view of the simulated world: the only code that reads ``MjData``.

In the dm_control manner, tasks, events and the coupling ask the view questions by meaning
(``ear_poses()``, ``gearshift_position()``, ``brake_teeth_engaged()``) and never index
MuJoCo's arrays themselves; elements are found by the full names of
:mod:`acoustic_sim.world.names`, so assets can be rebuilt without touching their readers.
Every array returned is a copy: a caller cannot write into the simulation through it. The
one writer is :mod:`acoustic_sim.world.actuation` (``tests/test_world_access.py`` holds
every other module to that).

:class:`SceneView` reads any model (sites, bodies, joints, cameras, controls, rays, the
renderer's picture); :class:`WorldView` adds the robot's head and ears, the cabin's levers
and the actuators, and needs a composed scene.

Frames: world is MuJoCo's (z up, metres, radians for joints). The head frame is the
renderer's (x forward, y toward the left ear, z up) and is derived from the ear sites.

The levers' geometry (detent angles, ratchet teeth) is read from the cabin model's custom
numerics into :class:`~acoustic_sim.world.lever_geometry.GearshiftGeometry` and
:class:`~acoustic_sim.world.lever_geometry.RatchetGeometry` (re-exported here).
"""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names
from acoustic_sim.world.lever_geometry import GearshiftGeometry, RatchetGeometry


@dataclasses.dataclass(frozen=True)
class ActuatorInfo:
    """Static description of the model's actuators.

    Attributes
    ----------
    names : tuple of str
        Full actuator names, in the model's order.
    force_limit : numpy.ndarray, shape (nu,)
        Largest force magnitude (N m or N) of each actuator; 0 where the model sets none.
    """

    names: tuple[str, ...]
    force_limit: np.ndarray


class SceneView:
    """Named read-only accessors over any MuJoCo model and its data (no robot needed).

    Parameters
    ----------
    model : mujoco.MjModel
    data : mujoco.MjData
        Read, never written. The view holds MuJoCo's named accessors, so it stays valid
        across ``mj_step`` and ``mj_resetData`` of this ``data``.
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if not isinstance(model, mujoco.MjModel) or not isinstance(data, mujoco.MjData):
            raise ConfigError(f"{type(self).__name__} needs a mujoco.MjModel and mujoco.MjData, got {type(model).__name__}, "
                              f"{type(data).__name__}")
        self.model = model
        self._data = data
        self._sites: dict[str, object] = {}
        self._bodies: dict[str, object] = {}
        self._joints: dict[str, object] = {}
        self._joint_addresses: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}

    # -- lookup ---------------------------------------------------------------------------------
    def has_site(self, name: str) -> bool:
        """Whether the model has a site of this full name."""
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, name) >= 0

    def has_body(self, name: str) -> bool:
        """Whether the model has a body of this full name."""
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name) >= 0

    def has_joint(self, name: str) -> bool:
        """Whether the model has a joint of this full name."""
        return mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, name) >= 0

    def _site(self, name: str):
        if name not in self._sites:
            if not self.has_site(name):
                raise ConfigError(f"the model has no site {name!r}")
            self._sites[name] = self._data.site(name)
        return self._sites[name]

    def _body(self, name: str):
        if name not in self._bodies:
            if not self.has_body(name):
                raise ConfigError(f"the model has no body {name!r}")
            self._bodies[name] = self._data.body(name)
        return self._bodies[name]

    def _joint(self, name: str):
        if name not in self._joints:
            if not self.has_joint(name):
                raise ConfigError(f"the model has no joint {name!r}")
            self._joints[name] = self._data.joint(name)
        return self._joints[name]

    # -- time -----------------------------------------------------------------------------------
    def time(self) -> float:
        """Simulation time (s)."""
        return float(self._data.time)
    # -- generic poses --------------------------------------------------------------------------
    def site_position(self, name: str) -> np.ndarray:
        """Position (m, world) of site ``name``, shape (3,)."""
        return self._site(name).xpos.copy()

    def site_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (m, world) and orientation (3x3, site to world) of site ``name``."""
        s = self._site(name)
        return s.xpos.copy(), s.xmat.reshape(3, 3).copy()

    def site_box(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A box-typed site: centre (m, world), orientation (3x3, box to world), half-sizes (m).

        Raises
        ------
        ConfigError
            If the site is not a box.
        """
        s = self._site(name)
        sid = int(s.id)
        if int(self.model.site_type[sid]) != int(mujoco.mjtGeom.mjGEOM_BOX):
            raise ConfigError(f"site {name!r} must be box-typed (it describes an air volume)")
        return s.xpos.copy(), s.xmat.reshape(3, 3).copy(), np.array(self.model.site_size[sid], dtype=float)

    def body_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (m, world) and orientation (3x3, body to world) of body ``name``."""
        b = self._body(name)
        return b.xpos.copy(), b.xmat.reshape(3, 3).copy()

    def body_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (nbody x 3, m, world) and quaternions (nbody x 4, w x y z, body to world)
        of every body, indexed by body id; copies, so the caller cannot change the state."""
        return np.array(self._data.xpos, dtype=np.float64), np.array(self._data.xquat, dtype=np.float64)

    def camera_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (m, world) and orientation (3x3, camera to world) of camera ``name``.

        MuJoCo's camera frame looks along its -z axis with +y up (the OpenGL convention).

        Raises
        ------
        ConfigError
            If the model has no camera of that name.
        """
        cid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_CAMERA, name)
        if cid < 0:
            raise ConfigError(f"the model has no camera {name!r}")
        return self._data.cam_xpos[cid].copy(), self._data.cam_xmat[cid].reshape(3, 3).copy()

    def joint_angle(self, name: str) -> float:
        """Position of a hinge or slide joint (rad or m)."""
        j = self._joint(name)
        if j.qpos.size != 1:
            raise ConfigError(f"joint {name!r} has {j.qpos.size} coordinates; joint_angle reads hinges and slides")
        return float(j.qpos[0])

    def joint_velocity(self, name: str) -> float:
        """Velocity of a hinge or slide joint (rad/s or m/s)."""
        j = self._joint(name)
        if j.qvel.size != 1:
            raise ConfigError(f"joint {name!r} has {j.qvel.size} velocities; joint_velocity reads hinges and slides")
        return float(j.qvel[0])

    def joint_states(self, names) -> tuple[np.ndarray, np.ndarray]:
        """Positions (rad or m) and velocities of several hinge or slide joints at once:
        two float64 arrays in the order of ``names`` (a sequence of joint names); the same
        numbers as :meth:`joint_angle` and :meth:`joint_velocity` one by one."""
        key = tuple(names)
        adr = self._joint_addresses.get(key)
        if adr is None:
            qpos, qvel = [], []
            for name in key:
                j = self._joint(name)
                if j.qpos.size != 1:
                    raise ConfigError(f"joint {name!r} has {j.qpos.size} coordinates; joint_states reads hinges and slides")
                qpos.append(self.model.jnt_qposadr[j.id])
                qvel.append(self.model.jnt_dofadr[j.id])
            adr = self._joint_addresses[key] = (np.asarray(qpos, np.int64), np.asarray(qvel, np.int64))
        return self._data.qpos[adr[0]], self._data.qvel[adr[1]]

    def geom_positions(self) -> np.ndarray:
        """Centres (ngeom x 3, m, world) of every geom, indexed by geom id (a copy)."""
        return np.array(self._data.geom_xpos, dtype=np.float64)

    def joint_axis(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """A joint's anchor point (m, world) and its unit axis (world), each shape (3,)."""
        jid = self._joint(name).id
        return self._data.xanchor[jid].copy(), self._data.xaxis[jid].copy()

    # -- controls, rays, pictures ---------------------------------------------------------------
    def control(self, name: str) -> float:
        """The control of actuator ``name`` now (a position servo's target, rad or m; a
        velocity servo's, rad/s)."""
        if mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_ACTUATOR, name) < 0:
            raise ConfigError(f"the model has no actuator {name!r}")
        return float(self._data.actuator(name).ctrl[0])

    def ray(self, origin, direction, *, geomgroup=None, static: bool = True, exclude_body: int = -1) -> tuple[float, int]:
        """The first geom a ray from ``origin`` (m, world) along unit ``direction`` hits
        (``mujoco.mj_ray``): its distance (m; -1 for none) and its geom id (-1 for none).
        ``geomgroup``: the six groups' 0/1 flags (None: all); ``static``: static geoms count;
        ``exclude_body``: a body id whose geoms are ignored (-1: none)."""
        geom = np.zeros(1, np.int32)
        hit = mujoco.mj_ray(self.model, self._data, origin, direction, geomgroup, int(static), exclude_body, geom)
        return hit, int(geom[0])

    def render(self, renderer, camera=-1, *, scene_option=None) -> np.ndarray:
        """The picture of the current state (H x W x 3 uint8) from ``camera`` (an id, a name or
        a ``mujoco.MjvCamera``) by ``renderer`` (a ``mujoco.Renderer`` of this model)."""
        renderer.update_scene(self._data, camera, scene_option=scene_option)
        return renderer.render()


class WorldView(SceneView):
    """Named read-only accessors over a composed scene: the robot's head and ears, the cabin's
    levers, the actuators, and every :class:`SceneView` getter (same parameters).

    Raises
    ------
    ConfigError
        If the model lacks the robot's ear sites or head body (every scene has them).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        super().__init__(model, data)
        for what, name, kind in (
            ("left ear site", names.EAR_LEFT_SITE, mujoco.mjtObj.mjOBJ_SITE),
            ("right ear site", names.EAR_RIGHT_SITE, mujoco.mjtObj.mjOBJ_SITE),
            ("head body", names.HEAD_BODY, mujoco.mjtObj.mjOBJ_BODY),
        ):
            if mujoco.mj_name2id(model, kind, name) < 0:
                raise ConfigError(f"the model has no {what} {name!r}: is the robot attached with prefix {names.ROBOT!r}?")
        self._ear_left = data.site(names.EAR_LEFT_SITE)
        self._ear_right = data.site(names.EAR_RIGHT_SITE)
        self._head = data.body(names.HEAD_BODY)
        self.gearshift_geometry: GearshiftGeometry | None = None
        """Detents of the cabin's gearshift; ``None`` in scenes without one."""
        self.ratchet_geometry: RatchetGeometry | None = None
        """Ratchet of the cabin's parking brake; ``None`` in scenes without one."""
        if self.has_joint(names.GEARSHIFT_JOINT):
            detents = self._numeric(names.GEAR_DETENTS_NUMERIC, "the detent angles (rad) of P, R, N, D", size=len(names.GEAR_NAMES))
            self.gearshift_geometry = GearshiftGeometry(detents_rad=tuple(float(v) for v in detents))
            self._gear_joint = self._joint(names.GEARSHIFT_JOINT)
        if self.has_joint(names.BRAKE_JOINT):
            teeth = self._numeric(names.BRAKE_TEETH_NUMERIC, "the lever's rest angle (rad) on each ratchet tooth")
            self.ratchet_geometry = RatchetGeometry(teeth_rad=tuple(float(v) for v in teeth))
            self._brake_joint = self._joint(names.BRAKE_JOINT)
            if not self.has_joint(names.BRAKE_PAWL_JOINT):
                raise ConfigError(f"the parking brake has no pawl joint {names.BRAKE_PAWL_JOINT!r} (its snap is the ratchet's click)")
            self._pawl_joint = self._joint(names.BRAKE_PAWL_JOINT)
        nu = model.nu
        limited = np.asarray(model.actuator_forcelimited, dtype=bool)
        span = np.max(np.abs(np.asarray(model.actuator_forcerange, dtype=float).reshape(nu, 2)), axis=1) if nu else np.zeros(0)
        self._actuators = ActuatorInfo(
            names=tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator{i}" for i in range(nu)),
            force_limit=np.where(limited, span, 0.0),
        )

    def _numeric(self, name: str, what: str, *, size: int | None = None) -> np.ndarray:
        i = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_NUMERIC, name)
        if i < 0:
            raise ConfigError(f"the model has no custom numeric {name!r} with {what}: the asset must declare it")
        adr, n = int(self.model.numeric_adr[i]), int(self.model.numeric_size[i])
        values = np.array(self.model.numeric_data[adr : adr + n], dtype=float)
        if (size is not None and values.size != size) or values.size == 0 or not np.all(np.isfinite(values)):
            expected = f"{size} finite values" if size is not None else "finite values"
            raise ConfigError(f"custom numeric {name!r} must hold {expected}: {what}; got {values.tolist()}")
        return values

    # -- head and ears --------------------------------------------------------------------------
    def ear_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (m, world) of the left and right ear-canal entrances, each shape (3,)."""
        return self._ear_left.xpos.copy(), self._ear_right.xpos.copy()

    def head_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Head centre (m, world) and orientation (3x3, head to world) from the ear sites.

        The centre is the midpoint of the ears; y points from the right ear to the left;
        x is the head body's forward axis made orthogonal to y; z = x cross y.

        Raises
        ------
        ConfigError
            If the ears coincide or the head's forward axis is parallel to the ear axis.
        """
        # Plain floats: this runs every control step and numpy's per-call cost dominates 3-vectors.
        lx, ly, lz = self._ear_left.xpos.tolist()
        rx, ry, rz = self._ear_right.xpos.tolist()
        yx, yy, yz = lx - rx, ly - ry, lz - rz
        span = math.sqrt(yx * yx + yy * yy + yz * yz)
        if span < 1e-3:
            raise ConfigError(f"the ear sites are {span * 1e3:.2f} mm apart: no interaural axis")
        yx, yy, yz = yx / span, yy / span, yz / span
        m = self._head.xmat.tolist()  # row-major 3x3: the body's x axis is entries 0, 3, 6
        fx, fy, fz = m[0], m[3], m[6]
        dot = fx * yx + fy * yy + fz * yz
        xx, xy, xz = fx - dot * yx, fy - dot * yy, fz - dot * yz
        nx = math.sqrt(xx * xx + xy * xy + xz * xz)
        if nx < 1e-6:
            raise ConfigError("the head body's forward axis is parallel to the ear axis")
        xx, xy, xz = xx / nx, xy / nx, xz / nx
        zx, zy, zz = xy * yz - xz * yy, xz * yx - xx * yz, xx * yy - xy * yx
        centre = np.array((0.5 * (lx + rx), 0.5 * (ly + ry), 0.5 * (lz + rz)))
        return centre, np.array(((xx, yx, zx), (xy, yy, zy), (xz, yz, zz)))

    def ear_spacing(self) -> float:
        """Distance (m) between the ear sites."""
        return float(np.linalg.norm(self._ear_left.xpos - self._ear_right.xpos))
    # -- cabin mechanisms -----------------------------------------------------------------------
    def _need(self, geometry, what: str):
        if geometry is None:
            raise ConfigError(f"this scene has no {what}")
        return geometry

    def gearshift_angle(self) -> float:
        """Gearshift hinge angle (rad, + toward D)."""
        try:
            return float(self._gear_joint.qpos[0])
        except AttributeError:
            raise ConfigError("this scene has no gearshift") from None

    def gearshift_position(self) -> str | None:
        """'P', 'R', 'N' or 'D' when the lever is in a detent's capture zone, else ``None``."""
        return self._need(self.gearshift_geometry, "gearshift").position(self.gearshift_angle())

    def brake_angle(self) -> float:
        """Parking-brake lever angle (rad, + pulled up)."""
        try:
            return float(self._brake_joint.qpos[0])
        except AttributeError:
            raise ConfigError("this scene has no parking brake") from None

    def pawl_angle(self) -> float:
        """Ratchet pawl angle (rad, 0 = resting on the pins' path, + = lifted)."""
        try:
            return float(self._pawl_joint.qpos[0])
        except AttributeError:
            raise ConfigError("this scene has no parking brake") from None

    def brake_teeth_engaged(self) -> int:
        """Number of ratchet teeth the brake lever has passed (0 = fully down)."""
        return self._need(self.ratchet_geometry, "parking brake").teeth_engaged(self.brake_angle())

    # -- actuators ------------------------------------------------------------------------------
    def actuator_info(self) -> ActuatorInfo:
        """Names and force limits of the model's actuators."""
        return self._actuators

    def actuator_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Actuator velocities (rad/s or m/s) and forces (N m or N), each shape (nu,)."""
        return self._data.actuator_velocity.copy(), self._data.actuator_force.copy()


__all__ = ["ActuatorInfo", "GearshiftGeometry", "RatchetGeometry", "SceneView", "WorldView"]
