"""The one writer of the simulation's state (``MjData``): acting on a composed scene.

Everything that changes ``MjData`` is here, so that what the world does has one door:
physics (:func:`step`, :func:`forward`, :func:`kinematics`, :func:`settle`), the robot's
start (:func:`home_pose`), its joints and servos (:func:`set_joint_position`,
:func:`set_control`, :func:`set_joint_force`), its hands (:func:`grasp`, :func:`release`,
with :func:`is_grasping`; the grip's anchor is written into ``MjModel.eq_data``, which is
part of the grasp), the arm's inverse kinematics (:func:`reach`, on a scratch copy) and the
mocap bodies (:func:`place_mocap`). Reads go through :mod:`acoustic_sim.world.view`;
``tests/test_world_access.py`` holds every other module to both rules.
"""

from __future__ import annotations

import mujoco
import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names

# -- physics ---------------------------------------------------------------------------------------


def step(model: mujoco.MjModel, data: mujoco.MjData, nstep: int = 1) -> None:
    """Advance the physics ``nstep`` timesteps (``mujoco.mj_step``)."""
    mujoco.mj_step(model, data, nstep)


def forward(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Compute every derived quantity of the current state without advancing time (``mj_forward``)."""
    mujoco.mj_forward(model, data)


def kinematics(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """Compute the poses (bodies, sites, geoms, cameras) of the current coordinates (``mj_kinematics``)."""
    mujoco.mj_kinematics(model, data)


def settle(model: mujoco.MjModel, data: mujoco.MjData, seconds: float) -> None:
    """Run physics for ``seconds`` (setting up a start state), then restart the clock at 0."""
    mujoco.mj_step(model, data, round(seconds / model.opt.timestep))
    data.time = 0.0
    mujoco.mj_forward(model, data)


def reference_pose(model: mujoco.MjModel) -> mujoco.MjData:
    """A fresh ``MjData`` at the model's reference pose (``qpos0``, where the scene placed
    everything), its kinematics computed: read it through a view."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return data


# -- joints and servos -----------------------------------------------------------------------------


def _element(model: mujoco.MjModel, kind: mujoco.mjtObj, what: str, count: int, element: str | int) -> int:
    """The id of a named element, or an id checked against ``count``."""
    if isinstance(element, (int, np.integer)):
        if not 0 <= element < count:
            raise ConfigError(f"{what} id {element} is out of range: the model has {count}")
        return int(element)
    i = mujoco.mj_name2id(model, kind, element)
    if i < 0:
        raise ConfigError(f"the model has no {what} {element!r}")
    return i


def home_pose(model: mujoco.MjModel, data: mujoco.MjData, joint_positions: dict | None = None) -> None:
    """The robot's seated rest pose, then ``mj_forward``, so every derived quantity is valid.

    The robot's coordinates and controls come from its ``home`` keyframe (position targets
    equal to the pose); everything else keeps its reference pose (the wheelchair where it was
    placed) and the mocap bodies stay put. ``joint_positions`` ({joint name: rad or m}) then
    sets other hinges, e.g. the cabin's levers.
    """
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, names.ROBOT + "home")
    robot_joints = [j for j in range(model.njnt) if (model.joint(j).name or "").startswith(names.ROBOT)]
    for j in robot_joints:
        adr = model.jnt_qposadr[j]
        data.qpos[adr] = model.key_qpos[key, adr]
    robot_actuators = [a for a in range(model.nu) if (model.actuator(a).name or "").startswith(names.ROBOT)]
    data.ctrl[robot_actuators] = model.key_ctrl[key, robot_actuators]
    for joint, value in (joint_positions or {}).items():
        set_joint_position(model, data, joint, value)
    mujoco.mj_forward(model, data)


def set_joint_position(model: mujoco.MjModel, data: mujoco.MjData, joint: str | int, value: float) -> None:
    """Put a hinge or slide joint (full name or id) at ``value`` (rad or m); nothing is
    recomputed (call :func:`forward` or :func:`kinematics` after the last one)."""
    j = _element(model, mujoco.mjtObj.mjOBJ_JOINT, "joint", model.njnt, joint)
    if int(model.jnt_type[j]) not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
        raise ConfigError(f"joint {joint!r} is not a hinge or slide: set_joint_position sets one coordinate")
    data.qpos[model.jnt_qposadr[j]] = value


def set_control(model: mujoco.MjModel, data: mujoco.MjData, actuator: str | int, value: float) -> None:
    """Set the control of an actuator (full name or id): a position servo's target (rad or
    m), a velocity servo's (rad/s), a motor's command; it acts from the next :func:`step`."""
    data.ctrl[_element(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "actuator", model.nu, actuator)] = value


def set_joint_force(model: mujoco.MjModel, data: mujoco.MjData, joint: str, force: float) -> None:
    """Apply a generalized force (N m or N) at a hinge or slide joint, from the next
    :func:`step` until it is set again (``qfrc_applied``: a hand the scene does not model)."""
    j = _element(model, mujoco.mjtObj.mjOBJ_JOINT, "joint", model.njnt, joint)
    data.qfrc_applied[model.jnt_dofadr[j]] = force


# -- the hands -------------------------------------------------------------------------------------


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


# -- mocap bodies ----------------------------------------------------------------------------------


def yaw_quaternion(yaw_deg: float) -> list[float]:
    """The quaternion (w, x, y, z) of a turn by ``yaw_deg`` (deg, counter-clockwise) about +z."""
    half = np.deg2rad(yaw_deg) / 2.0
    return [float(np.cos(half)), 0.0, 0.0, float(np.sin(half))]


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
    data.mocap_quat[m] = yaw_quaternion(yaw_deg)


__all__ = [
    "forward", "grasp", "home_pose", "is_grasping", "kinematics", "place_mocap", "reach", "reference_pose", "release",
    "set_control", "set_joint_force", "set_joint_position", "settle", "step", "yaw_quaternion",
]
