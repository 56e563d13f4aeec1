"""The composed scenes (``acoustic_sim.world.scenes``): names, physics without warnings, the
acoustic rooms derived from the MuJoCo air volumes, grasping the levers with the hands,
placing people, and the snapshot."""

from __future__ import annotations

import os
import subprocess
import sys

import mujoco
import numpy as np
import pytest
from test_assets import assert_no_warnings

from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import rotation_zyx
from acoustic_sim.world import names, scenes


@pytest.fixture(scope="module")
def cabin_model():
    return scenes.load_scene("cabin")


@pytest.fixture
def cabin():
    return scenes.load_scene("cabin")


def exists(model, kind, name) -> bool:
    return mujoco.mj_name2id(model, kind, name) >= 0


ROBOT_NAMES = [
    (mujoco.mjtObj.mjOBJ_BODY, names.HEAD_BODY), (mujoco.mjtObj.mjOBJ_BODY, names.ROBOT_ROOT_BODY),
    (mujoco.mjtObj.mjOBJ_SITE, names.EAR_LEFT_SITE), (mujoco.mjtObj.mjOBJ_SITE, names.EAR_RIGHT_SITE),
    *[(mujoco.mjtObj.mjOBJ_CAMERA, c) for c in names.EYE_CAMERAS],
    *[(k, j) for j in (*names.NECK_JOINTS, *names.EYE_JOINTS) for k in (mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_ACTUATOR)],
    *[(k, j) for s in names.ARM_SIDES for j in names.arm_joints(s) for k in (mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_ACTUATOR)],
    *[(mujoco.mjtObj.mjOBJ_BODY, names.hand_body(s)) for s in names.ARM_SIDES],
    *[(mujoco.mjtObj.mjOBJ_SITE, names.grasp_site(s)) for s in names.ARM_SIDES],
]
CABIN_NAMES = [
    *[(mujoco.mjtObj.mjOBJ_SITE, s) for s in (
        names.CABIN_INTERIOR_SITE, names.ALARM_SPEAKER_SITE, names.GEARSHIFT_KNOB_SITE, names.BRAKE_HANDLE_SITE,
        names.BRAKE_PAWL_SITE, names.IGNITION_SITE, names.HORN_SITE, names.CABIN_SEAT_SITE)],
    *[(mujoco.mjtObj.mjOBJ_JOINT, j) for j in (
        names.GEARSHIFT_JOINT, names.BRAKE_JOINT, names.BRAKE_PAWL_JOINT, names.GEAR_DETENT_JOINT)],
    (mujoco.mjtObj.mjOBJ_BODY, names.GEARSHIFT_HANDLE_BODY), (mujoco.mjtObj.mjOBJ_BODY, names.BRAKE_HANDLE_BODY),
    (mujoco.mjtObj.mjOBJ_ACTUATOR, names.BRAKE_RELEASE_ACTUATOR),
    (mujoco.mjtObj.mjOBJ_NUMERIC, names.GEAR_DETENTS_NUMERIC), (mujoco.mjtObj.mjOBJ_NUMERIC, names.BRAKE_TEETH_NUMERIC),
    *[(mujoco.mjtObj.mjOBJ_EQUALITY, names.grasp_equality(s)) for s in names.ARM_SIDES],
]
ROOM_NAMES = [
    (mujoco.mjtObj.mjOBJ_JOINT, names.WHEELCHAIR_ROOT_JOINT), (mujoco.mjtObj.mjOBJ_SITE, names.ROOM_INTERIOR_SITE),
    *[(k, j) for j in names.WHEEL_JOINTS for k in (mujoco.mjtObj.mjOBJ_JOINT, mujoco.mjtObj.mjOBJ_ACTUATOR)],
    (mujoco.mjtObj.mjOBJ_BODY, names.WHEELCHAIR_CHASSIS_BODY), (mujoco.mjtObj.mjOBJ_SITE, names.WHEELCHAIR_SEAT_SITE),
    (mujoco.mjtObj.mjOBJ_BODY, names.PERSON_ROOT_BODY), (mujoco.mjtObj.mjOBJ_BODY, names.PERSON_HEAD_BODY),
    (mujoco.mjtObj.mjOBJ_SITE, names.PERSON_MOUTH_SITE), (mujoco.mjtObj.mjOBJ_SITE, names.LOUDSPEAKER_SITE),
    (mujoco.mjtObj.mjOBJ_BODY, names.LOUDSPEAKER_BODY),
]


@pytest.mark.parametrize("name, expected", [("cabin", ROBOT_NAMES + CABIN_NAMES), ("room", ROBOT_NAMES + ROOM_NAMES)])
def test_scene_has_every_name_of_the_contract(name, expected):
    model, _, _ = scenes.load_scene(name)
    missing = [(kind.name, n) for kind, n in expected if not exists(model, kind, n)]
    assert not missing


@pytest.mark.parametrize("name", scenes.SCENES)
def test_scene_runs_2s_with_random_controls_without_warnings(name, rng):
    model, data, _ = scenes.load_scene(name)
    assert model.opt.timestep == scenes.TIMESTEP == 0.002
    most = 0
    lo, hi = model.actuator_ctrlrange.T
    for i in range(1000):
        if i % 8 == 0:
            data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
        most = max(most, data.ncon)
    assert_no_warnings(data)
    assert np.all(np.isfinite(data.qpos))
    assert most <= 12  # primitives only: a few contacts even with flailing arms


def test_build_scene_returns_an_editable_spec():
    spec = scenes.build_scene("room", config=scenes.RoomConfig(person_position=(1.0, 4.0)))
    assert isinstance(spec, mujoco.MjSpec)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.body(names.PERSON_ROOT_BODY).xpos, (1.0, 4.0, 0.0), atol=1e-12)


def test_bad_scene_requests_are_config_errors():
    with pytest.raises(ConfigError, match="unknown scene 'garage'"):
        scenes.build_scene("garage")
    with pytest.raises(ConfigError, match="RoomConfig"):
        scenes.build_scene("room", config=scenes.CabinConfig())
    with pytest.raises(ConfigError, match="wheelchair_position"):
        scenes.build_scene("room", config=scenes.RoomConfig(wheelchair_position=(7.0, 2.0)))
    with pytest.raises(ConfigError, match="gear"):
        scenes.CabinConfig(gear="X")
    with pytest.raises(ConfigError, match="brake_tooth"):
        scenes.CabinConfig(brake_tooth=8)
    with pytest.raises(ConfigError, match="person_position"):
        scenes.RoomConfig(person_position=(1.0, float("nan")))


# -- the head in the scenes ------------------------------------------------------------------------


@pytest.mark.parametrize("name", scenes.SCENES)
def test_at_zero_pose_the_ears_span_y_and_the_head_looks_along_x(name):
    model, _, _ = scenes.load_scene(name)
    data = mujoco.MjData(model)  # reference pose: every joint at zero, the chair where it was placed
    mujoco.mj_forward(model, data)
    left, right = data.site(names.EAR_LEFT_SITE).xpos, data.site(names.EAR_RIGHT_SITE).xpos
    axis = left - right
    assert np.linalg.norm(axis) == pytest.approx(names.EAR_SPACING_M, abs=1e-9)
    np.testing.assert_allclose(axis / np.linalg.norm(axis), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(data.body(names.HEAD_BODY).xmat.reshape(3, 3), np.eye(3), atol=1e-12)
    for cam in names.EYE_CAMERAS:
        np.testing.assert_allclose(-data.cam(cam).xmat.reshape(3, 3)[:, 2], [1, 0, 0], atol=1e-12)


def test_neck_turns_the_head_as_rotation_zyx_in_the_cabin(cabin):
    model, data, _ = cabin
    data.joint(names.NECK_JOINTS[0]).qpos[0] = np.deg2rad(90.0)
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.body(names.HEAD_BODY).xmat.reshape(3, 3), rotation_zyx(90.0, 0.0), atol=1e-12)
    axis = data.site(names.EAR_LEFT_SITE).xpos - data.site(names.EAR_RIGHT_SITE).xpos
    np.testing.assert_allclose(axis / np.linalg.norm(axis), [-1, 0, 0], atol=1e-12)  # turned left: left ear behind


# -- acoustic rooms --------------------------------------------------------------------------------


def test_cabin_acoustic_room_is_the_car_cabin_preset(cabin_model):
    model, _, info = cabin_model
    preset = room_preset("car_cabin")
    room = scenes.acoustic_room(model)
    assert room == info.room
    assert room.dimensions == pytest.approx(preset.dimensions, abs=1e-12)
    assert room.absorption == preset.absorption
    assert room.background_db_spl == preset.background_db_spl and room.ism_order == preset.ism_order
    # The robot's head in the driver's seat is the preset's listener.
    assert room.listener == pytest.approx(preset.listener, abs=1e-9)
    assert room.rt60_s == pytest.approx(preset.rt60_s, rel=1e-12)


def test_alarm_speaker_is_about_0_8_m_in_front_of_the_head(cabin_model):
    model, data, info = cabin_model
    speaker = scenes.to_room(model, data.site(names.ALARM_SPEAKER_SITE).xpos)
    offset = speaker - np.asarray(info.room.listener)
    assert 0.75 <= np.linalg.norm(offset) <= 0.85
    assert offset[0] > 0.75  # in front
    info.room.check_inside(speaker, what="alarm speaker")


def test_levers_are_on_the_correct_sides(cabin_model):
    _, data, _ = cabin_model
    head_y = data.site(names.EAR_LEFT_SITE).xpos[1] - names.EAR_SPACING_M / 2
    assert data.site(names.GEARSHIFT_KNOB_SITE).xpos[1] > head_y + 0.1  # gearshift on the robot's left
    assert data.site(names.BRAKE_HANDLE_SITE).xpos[1] < head_y - 0.1  # brake on the right


def test_room_acoustic_room_is_the_lab_preset_around_the_wheelchair():
    config = scenes.RoomConfig(wheelchair_position=(4.0, 1.5), wheelchair_yaw_deg=30.0)
    model, data, info = scenes.load_scene("room", config=config)
    preset = room_preset("lab")
    assert info.room.dimensions == pytest.approx(preset.dimensions)
    assert info.room.rt60_s == pytest.approx(preset.target_rt60_s, rel=1e-6)
    ears = scenes.to_room(model, (data.site(names.EAR_LEFT_SITE).xpos + data.site(names.EAR_RIGHT_SITE).xpos) / 2)
    np.testing.assert_allclose(info.room.listener, ears, atol=1e-9)
    assert info.room.listener[:2] == pytest.approx((4.0 + 0.12 * np.cos(np.pi / 6), 1.5 + 0.12 * np.sin(np.pi / 6)), abs=1e-9)


def test_acoustic_room_needs_an_air_volume():
    model = mujoco.MjModel.from_xml_path(str(scenes.ASSET_DIR / "musashi_head" / "scene.xml"))
    with pytest.raises(ConfigError, match="air-volume site"):
        scenes.acoustic_room(model)


# -- levers in the scene: initial state and the hands ---------------------------------------------


def test_cabin_starts_with_the_configured_gear_and_brake_and_holds_them():
    model, data, _ = scenes.load_scene("cabin", config=scenes.CabinConfig(gear="R", brake_tooth=3))
    mujoco.mj_step(model, data, 500)
    assert np.rad2deg(data.joint(names.GEARSHIFT_JOINT).qpos[0]) == pytest.approx(15.0, abs=0.2)
    assert np.rad2deg(data.joint(names.BRAKE_JOINT).qpos[0]) == pytest.approx(22.0, abs=0.3)


def arm_actuators(model, side):
    return [model.actuator(j).id for j in names.arm_joints(side)]


def palm_to_handle(data, side):
    return float(np.linalg.norm(data.site(names.grasp_site(side)).xpos - data.site(names.GRASP_TARGET_SITES[side]).xpos))


def reach_handle(model, data, side):
    """Put the palm on the handle with the arm's servos and close the hand."""
    data.ctrl[arm_actuators(model, side)] = scenes.reach(model, data, side, data.site(names.GRASP_TARGET_SITES[side]).xpos)
    mujoco.mj_step(model, data, 500)
    assert palm_to_handle(data, side) < 0.03
    assert scenes.grasp(model, data, side)
    assert scenes.is_grasping(model, data, side)


def test_left_hand_shifts_gear_and_lets_go(cabin):
    model, data, _ = cabin
    gear = data.joint(names.GEARSHIFT_JOINT)
    reach_handle(model, data, "left")
    pivot = data.body(names.GEARSHIFT_HANDLE_BODY).xpos.copy()
    knob = data.site(names.GEARSHIFT_KNOB_SITE).xpos
    radius = np.linalg.norm(knob - pivot)
    grip = data.site(names.grasp_site("left")).xpos - knob
    for target_deg in (15.0, 30.0):  # P -> R -> N
        lean = np.deg2rad(22.5 - target_deg)  # the lever leans 22.5 deg forward in P
        target = pivot + radius * np.array([np.sin(lean), 0.0, np.cos(lean)]) + grip
        data.ctrl[arm_actuators(model, "left")] = scenes.reach(model, data, "left", target)
        mujoco.mj_step(model, data, 500)
        assert np.rad2deg(gear.qpos[0]) == pytest.approx(target_deg, abs=2.0)
    scenes.release(model, data, "left")
    assert not scenes.is_grasping(model, data, "left")
    data.ctrl[arm_actuators(model, "left")] = 0.0  # the arm drops to its side
    mujoco.mj_step(model, data, 500)
    assert palm_to_handle(data, "left") > 0.2
    assert np.rad2deg(gear.qpos[0]) == pytest.approx(30.0, abs=0.2)  # the lever stays in N
    assert_no_warnings(data)


def test_right_hand_pulls_the_brake_and_the_ratchet_holds_it(cabin):
    model, data, _ = cabin
    brake = data.joint(names.BRAKE_JOINT)
    reach_handle(model, data, "right")
    pivot = data.body(names.BRAKE_HANDLE_BODY).xpos.copy()
    handle = data.site(names.BRAKE_HANDLE_SITE).xpos
    radius = np.linalg.norm(handle - pivot)
    grip = data.site(names.grasp_site("right")).xpos - handle
    for angle in np.linspace(2.0, 27.0, 12):  # pull up past tooth 3's click (23 deg) in 1.8 s
        rise = np.deg2rad(10.0 + angle)  # the lever rises 10 deg above horizontal when down
        target = pivot + radius * np.array([np.cos(rise), 0.0, np.sin(rise)]) + grip
        data.ctrl[arm_actuators(model, "right")] = scenes.reach(model, data, "right", target)
        mujoco.mj_step(model, data, 75)
    mujoco.mj_step(model, data, 250)
    assert 23.2 < np.rad2deg(brake.qpos[0]) < 29.0  # past tooth 3, short of tooth 4
    scenes.release(model, data, "right")
    data.ctrl[arm_actuators(model, "right")] = 0.0
    mujoco.mj_step(model, data, 500)
    assert palm_to_handle(data, "right") > 0.2
    assert np.rad2deg(brake.qpos[0]) == pytest.approx(names.BRAKE_TOOTH_ANGLES_DEG[2], abs=0.3)  # on tooth 3
    assert_no_warnings(data)


def test_grasp_refuses_a_handle_out_of_reach_and_scenes_without_levers(cabin_model):
    model, _, _ = cabin_model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)  # arms hanging straight down: the palms are far from the handles
    assert not scenes.grasp(model, data, "left")
    assert not scenes.is_grasping(model, data, "left")
    with pytest.raises(ConfigError, match="side"):
        scenes.grasp(model, data, "middle")
    room_model, room_data, _ = scenes.load_scene("room")
    with pytest.raises(ConfigError, match="no grasp"):
        scenes.grasp(room_model, room_data, "left")


def test_reach_refuses_unreachable_targets(cabin_model):
    model, data, _ = cabin_model
    with pytest.raises(ConfigError, match="cannot reach"):
        scenes.reach(model, data, "left", (3.0, 1.0, 1.0))
    with pytest.raises(ConfigError, match="3 finite"):
        scenes.reach(model, data, "left", (1.0, 1.0))


# -- the room: driving and placing -----------------------------------------------------------------


def test_wheelchair_carries_the_robot():
    model, data, _ = scenes.load_scene("room")
    start = data.site(names.EAR_LEFT_SITE).xpos.copy()
    for joint in names.WHEEL_JOINTS:
        data.actuator(joint).ctrl[0] = 2.0  # 0.6 m/s
    mujoco.mj_step(model, data, 1000)
    moved = data.site(names.EAR_LEFT_SITE).xpos - start
    assert 0.9 < moved[0] < 1.25 and abs(moved[1]) < 0.02 and abs(moved[2]) < 0.01
    assert_no_warnings(data)


def test_place_mocap_moves_the_person_and_refuses_other_bodies():
    model, data, _ = scenes.load_scene("room")
    scenes.place_mocap(model, data, names.PERSON_ROOT_BODY, (1.0, 1.0, 0.0), yaw_deg=90.0)
    mujoco.mj_forward(model, data)
    mouth = data.site(names.PERSON_MOUTH_SITE).xpos
    np.testing.assert_allclose(mouth[:2], (1.0, 1.095), atol=1e-9)  # facing +y, mouth 9.5 cm in front
    assert 1.5 < mouth[2] < 1.65
    with pytest.raises(ConfigError, match="not a mocap body"):
        scenes.place_mocap(model, data, names.WHEELCHAIR_CHASSIS_BODY, (1.0, 1.0, 0.0))
    with pytest.raises(ConfigError, match="finite"):
        scenes.place_mocap(model, data, names.LOUDSPEAKER_BODY, (1.0, np.inf, 0.0))


# -- snapshot --------------------------------------------------------------------------------------


def test_snapshot_writes_png_files(tmp_path):
    # A fresh interpreter: MuJoCo's OpenGL backend is fixed when mujoco is first imported.
    code = (
        "import sys; from pathlib import Path; from acoustic_sim.world.snapshot import snapshot\n"
        "for name in ('cabin', 'room'): snapshot(name, Path(sys.argv[1]) / f'{name}.png', width=96, height=64)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    subprocess.run([sys.executable, "-c", code, str(tmp_path)], check=True, env=env, timeout=120)
    from PIL import Image

    for name in ("cabin", "room"):
        image = np.asarray(Image.open(tmp_path / f"{name}.png"))
        assert image.shape == (64, 96, 3)
        assert image.std() > 10  # a picture, not a blank frame


def test_snapshot_rejects_bad_arguments(tmp_path):
    from acoustic_sim.world.snapshot import snapshot

    with pytest.raises(ConfigError, match="unknown scene"):
        snapshot("garage", tmp_path / "x.png")
    with pytest.raises(ConfigError, match="width"):
        snapshot("cabin", tmp_path / "x.png", width=8)
    with pytest.raises(ConfigError, match=".png"):
        snapshot("cabin", tmp_path / "x.jpg")
