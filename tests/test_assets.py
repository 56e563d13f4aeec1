"""The MuJoCo assets on their own (menagerie style): every ``assets/*/scene.xml`` compiles and
runs with random controls without a MuJoCo warning; the head's geometry and sign
conventions; the cabin's detents and ratchet; the wheelchair's drive; the generated meshes."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import mujoco
import numpy as np
import pytest

from acoustic_sim.frames import rotation_zyx
from acoustic_sim.world import names

ASSETS = Path(__file__).resolve().parents[1] / "assets"
SCENE_FILES = sorted(ASSETS.glob("*/scene.xml"))


def run_random(model: mujoco.MjModel, data: mujoco.MjData, seconds: float, rng: np.random.Generator) -> None:
    """Step with a new uniformly random control every 16 ms."""
    lo, hi = model.actuator_ctrlrange.T
    steps_per_control = 8
    for i in range(round(seconds / model.opt.timestep)):
        if model.nu and i % steps_per_control == 0:
            data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)


def assert_no_warnings(data: mujoco.MjData) -> None:
    counts = {mujoco.mjtWarning(i).name: int(w.number) for i, w in enumerate(data.warning) if w.number}
    assert not counts, f"MuJoCo warnings: {counts}"


def test_every_asset_has_a_scene():
    folders = {p.parent.name for p in SCENE_FILES}
    assert {"musashi_head", "car_cabin", "wheelchair", "person", "loudspeaker"} <= folders


@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.parent.name)
def test_scene_runs_2s_with_random_controls_without_warnings(path, rng):
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    assert model.opt.timestep == pytest.approx(0.002)
    run_random(model, data, 2.0, rng)
    assert_no_warnings(data)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))


def test_room_shell_compiles_with_a_box_air_volume():
    model = mujoco.MjModel.from_xml_path(str(ASSETS / "wheelchair" / "room.xml"))
    site = model.site(names.ROOM_INTERIOR_SITE)
    assert site.type[0] == mujoco.mjtGeom.mjGEOM_BOX
    np.testing.assert_allclose(2 * site.size, (6.0, 5.0, 3.0))


# -- the head --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def head():
    model = mujoco.MjModel.from_xml_path(str(ASSETS / "musashi_head" / "scene.xml"))
    return model, mujoco.MjData(model)


def pose_head(model, data, yaw_deg=0.0, pitch_deg=0.0, eye_yaw_deg=0.0, eye_pitch_deg=0.0):
    mujoco.mj_resetData(model, data)
    for joint, deg in (("neck_yaw", yaw_deg), ("neck_pitch", pitch_deg), ("eye_yaw", eye_yaw_deg), ("eye_pitch", eye_pitch_deg)):
        data.joint(joint).qpos[0] = np.deg2rad(deg)
    mujoco.mj_forward(model, data)


def test_ear_spacing_matches_the_kemar_head(head):
    model, data = head
    pose_head(model, data)
    spacing = np.linalg.norm(data.site("ear_left").xpos - data.site("ear_right").xpos)
    assert spacing == pytest.approx(names.EAR_SPACING_M, abs=1e-9)
    assert 0.145 <= names.EAR_SPACING_M <= 0.16


def test_at_zero_pose_the_ear_axis_is_y_and_the_eyes_look_along_x(head):
    model, data = head
    pose_head(model, data)
    axis = data.site("ear_left").xpos - data.site("ear_right").xpos
    np.testing.assert_allclose(axis / np.linalg.norm(axis), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(data.body("head").xmat.reshape(3, 3), np.eye(3), atol=1e-12)
    for cam in ("eye_left", "eye_right"):
        r = data.cam(cam).xmat.reshape(3, 3)
        np.testing.assert_allclose(-r[:, 2], [1, 0, 0], atol=1e-12)  # cameras look along their -z
        np.testing.assert_allclose(r[:, 1], [0, 0, 1], atol=1e-12)  # image up is world up
    assert data.cam("eye_left").xpos[1] > 0 > data.cam("eye_right").xpos[1]


@pytest.mark.parametrize("yaw, pitch", [(90.0, 0.0), (-90.0, 0.0), (0.0, 45.0), (0.0, -45.0), (30.0, 20.0)])
def test_neck_follows_the_frames_convention(head, yaw, pitch):
    model, data = head
    pose_head(model, data, yaw, pitch)
    np.testing.assert_allclose(data.body("head").xmat.reshape(3, 3), rotation_zyx(yaw, pitch), atol=1e-12)


def test_turning_left_and_nodding_move_the_face_the_right_way(head):
    model, data = head
    pose_head(model, data, yaw_deg=90.0)
    forward = data.body("head").xmat.reshape(3, 3)[:, 0]
    np.testing.assert_allclose(forward, [0, 1, 0], atol=1e-12)  # + yaw = turn left
    pose_head(model, data, pitch_deg=30.0)
    assert data.body("head").xmat.reshape(3, 3)[2, 0] < -0.4  # + pitch = nose down
    pose_head(model, data, eye_yaw_deg=20.0, eye_pitch_deg=10.0)
    look = -data.cam("eye_left").xmat.reshape(3, 3)[:, 2]
    np.testing.assert_allclose(look, rotation_zyx(20.0, 10.0)[:, 0], atol=1e-12)


def test_joint_ranges(head):
    model, _ = head
    for joint, lo, hi in (("neck_yaw", -90, 90), ("neck_pitch", -45, 45)):
        np.testing.assert_allclose(np.rad2deg(model.joint(joint).range), (lo, hi))


def test_every_robot_joint_has_a_position_actuator_of_its_name(head):
    model, _ = head
    strip = len(names.ROBOT)
    expected = [n[strip:] for n in (*names.NECK_JOINTS, *names.EYE_JOINTS, *names.arm_joints("left"), *names.arm_joints("right"))]
    assert sorted(model.joint(j).name for j in range(model.njnt)) == sorted(expected)
    for joint in expected:
        act = model.actuator(joint)
        assert act.trntype[0] == mujoco.mjtTrn.mjTRN_JOINT and act.trnid[0] == model.joint(joint).id
        assert act.biastype[0] == mujoco.mjtBias.mjBIAS_AFFINE  # a position servo
        np.testing.assert_allclose(act.ctrlrange, model.joint(joint).range)


def test_home_keyframe_holds_the_seated_pose(head):
    model, data = head
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    q0 = data.qpos.copy()
    for _ in range(500):
        mujoco.mj_step(model, data)
    assert np.max(np.abs(data.qpos - q0)) < np.deg2rad(2.5)  # sag of the position servos under gravity


# -- the cabin's mechanisms ------------------------------------------------------------------------


class Cabin:
    def __init__(self):
        self.model = mujoco.MjModel.from_xml_path(str(ASSETS / "car_cabin" / "scene.xml"))
        self.data = mujoco.MjData(self.model)
        self.gear = self.data.joint("gearshift")
        self.brake = self.data.joint("brake")
        self.pawl = self.data.joint("pawl")

    def numeric(self, name):
        n = self.model.numeric(name)
        return np.array(self.model.numeric_data[n.adr[0] : n.adr[0] + n.size[0]])

    def step(self, n=1, gear_torque=0.0, brake_torque=0.0, release=0.0):
        for _ in range(n):
            self.gear.qfrc_applied[0] = gear_torque
            self.brake.qfrc_applied[0] = brake_torque
            self.data.ctrl[0] = release
            mujoco.mj_step(self.model, self.data)

    def pull_brake_to(self, angle_deg, speed_deg_s=40.0):
        """Drive the brake lever up like a hand would (a stiff PD through its dof), hold it."""
        target = np.rad2deg(self.brake.qpos[0])
        for i in range(int(np.ceil(angle_deg / (speed_deg_s * self.model.opt.timestep))) + 100):
            target = min(angle_deg, target + speed_deg_s * self.model.opt.timestep)
            self.step(brake_torque=300.0 * (np.deg2rad(target) - self.brake.qpos[0]) - 5.0 * self.brake.qvel[0])


@pytest.fixture
def cabin():
    return Cabin()


def test_mechanism_angles_match_the_names_contract(cabin):
    np.testing.assert_allclose(cabin.numeric(names.GEAR_DETENTS_NUMERIC[len(names.CAR):]),
                               np.deg2rad(names.GEAR_DETENT_ANGLES_DEG), atol=1e-6)
    np.testing.assert_allclose(cabin.numeric(names.BRAKE_TEETH_NUMERIC[len(names.CAR):]),
                               np.deg2rad(names.BRAKE_TOOTH_ANGLES_DEG), atol=1e-6)


def test_cabin_interior_is_the_car_cabin_preset_box(cabin):
    site = cabin.model.site(names.CABIN_INTERIOR_SITE[len(names.CAR):])
    assert site.type[0] == mujoco.mjtGeom.mjGEOM_BOX
    np.testing.assert_allclose(site.pos - site.size, 0.0, atol=1e-12)  # the cabin frame is the room frame
    np.testing.assert_allclose(2 * site.size, (2.0, 1.5, 1.2))


@pytest.mark.parametrize("gear", range(4), ids=names.GEAR_NAMES)
def test_gearshift_holds_in_each_detent_under_gravity_and_disturbances(cabin, gear, rng):
    detent = np.deg2rad(names.GEAR_DETENT_ANGLES_DEG[gear])
    cabin.gear.qpos[0] = detent
    mujoco.mj_forward(cabin.model, cabin.data)
    worst = 0.0
    for _ in range(50):  # 1 s of random shoves of up to 0.3 N m, changed every 20 ms
        cabin.step(10, gear_torque=rng.uniform(-0.3, 0.3))
        worst = max(worst, abs(cabin.gear.qpos[0] - detent))
    cabin.step(250)
    assert worst < np.deg2rad(2.0)
    assert cabin.gear.qpos[0] == pytest.approx(detent, abs=np.deg2rad(0.2))
    assert_no_warnings(cabin.data)


def test_gearshift_needs_a_torque_threshold_to_change_gear(cabin):
    detents = np.deg2rad(names.GEAR_DETENT_ANGLES_DEG)
    cabin.gear.qpos[0] = detents[1]  # R
    mujoco.mj_forward(cabin.model, cabin.data)
    cabin.step(250, gear_torque=0.5)  # below the threshold: stays in R
    assert cabin.gear.qpos[0] == pytest.approx(detents[1], abs=np.deg2rad(2.0))
    cabin.step(250)
    # Above it: push until the lever leaves R, then let go; it drops into N, the next detent.
    for _ in range(500):
        cabin.step(gear_torque=1.5)
        if cabin.gear.qpos[0] > detents[1] + np.deg2rad(8.0):
            break
    cabin.step(500)
    assert cabin.gear.qpos[0] == pytest.approx(detents[2], abs=np.deg2rad(0.2))
    # And back toward P the same way.
    for _ in range(500):
        cabin.step(gear_torque=-1.5)
        if cabin.gear.qpos[0] < detents[2] - np.deg2rad(8.0):
            break
    cabin.step(500)
    assert cabin.gear.qpos[0] == pytest.approx(detents[1], abs=np.deg2rad(0.2))


@pytest.mark.parametrize("tooth", [1, 4, 7])
def test_ratchet_holds_the_brake_on_the_tooth_it_was_pulled_to(cabin, tooth):
    teeth = names.BRAKE_TOOTH_ANGLES_DEG
    cabin.pull_brake_to(teeth[tooth - 1] + 3.0)  # past the click of tooth k, short of tooth k + 1
    cabin.step(500)  # the hand lets go
    assert np.rad2deg(cabin.brake.qpos[0]) == pytest.approx(teeth[tooth - 1], abs=0.3)
    assert_no_warnings(cabin.data)


def test_ratchet_clicks_once_per_tooth_and_lets_go_on_release(cabin):
    lifted, clicks = False, 0
    for i in range(1500):  # up to 54 deg at 40 deg/s, then hold
        target = min(54.0, 40.0 * cabin.model.opt.timestep * i)
        cabin.step(brake_torque=300.0 * (np.deg2rad(target) - cabin.brake.qpos[0]) - 5.0 * cabin.brake.qvel[0])
        pawl = np.rad2deg(cabin.pawl.qpos[0])
        if not lifted and pawl > 4.0:
            lifted = True
        elif lifted and pawl < 1.5:
            lifted, clicks = False, clicks + 1
    assert clicks == len(names.BRAKE_TOOTH_ANGLES_DEG)
    cabin.step(500)
    assert np.rad2deg(cabin.brake.qpos[0]) == pytest.approx(names.BRAKE_TOOTH_ANGLES_DEG[-1], abs=0.3)
    cabin.step(500, release=1.0)  # the release button lifts the pawl: the lever falls
    assert np.rad2deg(cabin.brake.qpos[0]) < 0.5
    cabin.step(250)
    assert np.rad2deg(cabin.pawl.qpos[0]) < 0.5  # the pawl is back, ready for the next pull


def test_brake_released_mid_click_falls_to_the_tooth_below(cabin):
    teeth = names.BRAKE_TOOTH_ANGLES_DEG
    cabin.pull_brake_to(teeth[2] + 0.5)  # tooth 3's pin is under the pawl, not yet past it
    assert np.rad2deg(cabin.pawl.qpos[0]) > 4.0
    cabin.step(500)
    assert np.rad2deg(cabin.brake.qpos[0]) == pytest.approx(teeth[1], abs=0.3)


# -- the wheelchair --------------------------------------------------------------------------------


def test_wheelchair_drives_straight_and_turns_on_the_spot():
    model = mujoco.MjModel.from_xml_path(str(ASSETS / "wheelchair" / "scene.xml"))
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, 250)
    assert data.ncon == 4  # two wheels and two casters on the floor, nothing else
    data.ctrl[:] = (1.0, 1.0)  # 1 rad/s = 0.3 m/s
    mujoco.mj_step(model, data, 1500)
    x, y = data.qpos[:2]
    assert 0.75 < x < 0.9 and abs(y) < 0.01
    data.ctrl[:] = (-1.0, 1.0)
    mujoco.mj_step(model, data, 500)
    w, _, _, z = data.qpos[3:7]
    assert np.rad2deg(2 * np.arctan2(z, w)) > 20.0  # right wheel forward: turns left
    assert_no_warnings(data)


# -- meshes ----------------------------------------------------------------------------------------


def test_pinna_meshes_are_what_the_committed_script_writes(tmp_path):
    spec = importlib.util.spec_from_file_location("make_meshes", ASSETS / "musashi_head" / "make_meshes.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--out", str(tmp_path)])
    for side in ("left", "right"):
        name = f"pinna_{side}.stl"
        assert (tmp_path / name).read_bytes() == (ASSETS / "musashi_head" / "assets" / name).read_bytes()
        verts, faces = module.pinna_mesh(side)
        assert module.signed_volume(verts, faces) > 5e-6  # closed, outward normals, several cm^3
        edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        assert np.all(counts == 2)  # watertight: every edge shared by exactly two triangles
