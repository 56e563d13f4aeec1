"""The world view and the coupling: named reads, the room frame, the clock, the head turn, emitters."""

import mujoco
import numpy as np
import pytest

from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import block_length, frame_end_sample, rotation_zyx, vec_to_sph, world_to_head
from acoustic_sim.world import names, scenes
from acoustic_sim.world.coupling import Coupling
from acoustic_sim.world.room_box import RoomFrame
from acoustic_sim.world.egonoise import MotorEgoNoise
from acoustic_sim.world.events import EventsConfig
from acoustic_sim.world.view import WorldView

DEG = np.pi / 180.0


@pytest.fixture(scope="module")
def cabin():
    return scenes.load_scene("cabin")


def settle(c, seconds):
    for _ in range(round(seconds * 62.5)):
        c.advance()


def level_db(x):
    return 10 * np.log10(np.mean(x**2, axis=-1))


# -- the view ---------------------------------------------------------------------------------------


def test_view_reads_by_name_and_returns_copies(cabin):
    model, data, _ = cabin
    v = WorldView(model, data)
    left, right = v.ear_poses()
    assert np.allclose(left, data.site(names.EAR_LEFT_SITE).xpos) and np.allclose(right, data.site(names.EAR_RIGHT_SITE).xpos)
    assert v.ear_spacing() == pytest.approx(names.EAR_SPACING_M, abs=1e-6)
    left[:] = 0.0  # a copy: the simulation is untouched
    assert not np.allclose(data.site(names.EAR_LEFT_SITE).xpos, 0.0)
    centre, rot = v.head_pose()
    assert np.allclose(centre, 0.5 * (v.ear_poses()[0] + v.ear_poses()[1]))
    assert np.allclose(rot @ rot.T, np.eye(3)) and np.linalg.det(rot) == pytest.approx(1.0)
    assert np.allclose(rot[:, 1], (v.ear_poses()[0] - v.ear_poses()[1]) / v.ear_spacing())  # y toward the left ear
    assert rot[0, 0] > 0.99  # the seated robot faces +x
    assert v.gearshift_position() == "P" and v.brake_teeth_engaged() == 0
    assert v.gearshift_geometry.detents_rad == pytest.approx(np.deg2rad(names.GEAR_DETENT_ANGLES_DEG), abs=1e-5)
    assert v.ratchet_geometry.teeth_rad == pytest.approx(np.deg2rad(names.BRAKE_TOOTH_ANGLES_DEG), abs=1e-5)
    speeds, forces = v.actuator_state()
    assert speeds.shape == forces.shape == (model.nu,)
    assert v.actuator_info().names[0] and len(v.actuator_info().names) == model.nu
    pos, mat = v.site_pose(names.ALARM_SPEAKER_SITE)
    assert pos.shape == (3,) and mat.shape == (3, 3)
    assert v.time() == pytest.approx(data.time)
    # Several joints at once: the same numbers as one by one, in the order asked.
    saved = data.qpos.copy(), data.qvel.copy()
    data.qpos[:] = np.linspace(-0.5, 0.5, model.nq)
    data.qvel[:] = np.linspace(1.0, -1.0, model.nv)
    joints = [model.joint(j).name for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE][::-3]
    qpos, qvel = v.joint_states(joints)
    assert len(joints) > 3
    assert np.array_equal(qpos, [v.joint_angle(j) for j in joints])
    assert np.array_equal(qvel, [v.joint_velocity(j) for j in joints])
    data.qpos[:], data.qvel[:] = saved  # the module's other tests share this world


def test_view_errors(cabin):
    model, data, _ = cabin
    v = WorldView(model, data)
    with pytest.raises(ConfigError, match="no site 'car/nowhere'"):
        v.site_position("car/nowhere")
    with pytest.raises(ConfigError, match="no joint 'nowhere'"):
        v.joint_states(["nowhere"])
    with pytest.raises(ConfigError, match="must be box-typed"):
        v.site_box(names.ALARM_SPEAKER_SITE)
    room_model, room_data, _ = scenes.load_scene("room")
    rv = WorldView(room_model, room_data)
    with pytest.raises(ConfigError, match="no gearshift"):
        rv.gearshift_position()
    with pytest.raises(ConfigError, match="no parking brake"):
        rv.brake_teeth_engaged()
    bare = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    with pytest.raises(ConfigError, match="no left ear site"):
        WorldView(bare, mujoco.MjData(bare))
    with pytest.raises(ConfigError, match="mujoco.MjModel"):
        WorldView("model", "data")


# -- the room frame -----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", scenes.SCENES)
def test_room_frame_matches_the_scene(name):
    model, data, info = scenes.load_scene(name)
    v = WorldView(model, data)
    site = names.CABIN_INTERIOR_SITE if name == "cabin" else names.ROOM_INTERIOR_SITE
    frame = RoomFrame.from_box(*v.site_box(site))
    at_rest = scenes.room_frame(model, site)  # read at qpos0, where the scenes place the box
    assert np.allclose(frame.origin, at_rest.origin) and np.allclose(frame.rotation, at_rest.rotation)
    assert np.allclose(frame.dimensions, at_rest.dimensions)
    assert np.allclose(frame.dimensions, info.room.dimensions)
    centre, _ = v.head_pose()
    assert np.allclose(frame.to_room(centre), info.room.listener, atol=1e-6)
    p = np.array([[0.3, 0.2, 0.1], [1.0, 1.0, 1.0]])
    assert np.allclose(frame.to_world(frame.to_room(p)), p)


def test_entry_point_is_where_the_straight_path_to_the_listener_enters():
    frame = RoomFrame.from_box([2.0, 1.0, 1.0], np.eye(3), [2.0, 1.0, 1.0])  # room [0, 4] x [0, 2] x [0, 2]
    head = np.array([3.0, 0.5, 1.0])
    # 3 m beside the room's y = 0 wall and 1 m ahead of the head: the straight path reaches
    # y = 0.1 (the margin) after 0.4 of its 3.5 m across, not at the point nearest the source.
    source = np.array([4.0, -3.0, 1.0])
    entry = frame.entry_point(source, head, 0.1)
    assert entry[1] == pytest.approx(0.1)
    d, e = source - head, entry - head
    assert np.allclose(np.cross(d, e), 0.0) and np.dot(d, e) > 0  # on the segment, toward the source
    assert np.allclose(entry, head + (0.4 / 3.5) * d)
    assert not np.allclose(entry, [3.9, 0.1, 1.0])  # the point nearest the source, the law until 2026-12-04
    # Through a corner region the first wall reached decides; a point inside is its own entry.
    assert np.allclose(frame.entry_point([10.0, 1.0, 1.0], [2.0, 1.0, 1.0], 0.1), [3.9, 1.0, 1.0])
    assert np.allclose(frame.entry_point([1.0, 1.5, 0.5], head, 0.1), [1.0, 1.5, 0.5])
    # A listener against a wall is first clipped into the shrunk box.
    assert np.allclose(frame.entry_point([2.0, -5.0, 1.0], [2.0, 0.0, 1.0], 0.1), [2.0, 0.1, 1.0])


def test_room_frame_rotated_box():
    frame = RoomFrame.from_box([1.0, 2.0, 1.0], rotation_zyx(90.0), [2.0, 1.0, 1.0])
    assert np.allclose(frame.to_room([1.0, 2.0, 1.0]), [2.0, 1.0, 1.0])  # the centre
    assert np.allclose(frame.to_room([1.0, 3.0, 1.0]), [3.0, 1.0, 1.0])  # world +y is the room's +x
    assert np.allclose(frame.rotation_to_room(rotation_zyx(90.0)), np.eye(3))
    assert np.allclose(frame.entry_point([9.0, 1.0, 1.0], [2.0, 1.0, 1.0], 0.1), [3.9, 1.0, 1.0])
    with pytest.raises(ConfigError, match="positive half-sizes"):
        RoomFrame.from_box([0, 0, 0], np.eye(3), [1.0, 0.0, 1.0])


# -- the coupling ---------------------------------------------------------------------------------------


def test_head_turn_left_puts_the_front_source_at_minus_90(kemar):
    """Turning the head 90 deg to the left puts the alarm, straight ahead, at azimuth -90."""
    c = Coupling.from_scene("cabin", rng=np.random.default_rng(0), hrtf=kemar, scene_config=scenes.CabinConfig(gear="R"),
                            background=False)
    r = c.renderer

    def listen(seconds):
        return np.concatenate([c.step() for _ in range(round(seconds * 62.5))], axis=1)

    def direction():
        return vec_to_sph(world_to_head(r.sources["alarm"].position, r.head_position, r.head_rotation))

    before = listen(1.2)
    az, el = direction()
    assert abs(az) < 2.0 and -15.0 < el < 0.0  # ahead, a little below the ears
    c.data.actuator(names.NECK_JOINTS[0]).ctrl[0] = 90.0 * DEG  # neck yaw: + turns left
    listen(1.0)
    after = listen(1.2)
    az, _ = direction()
    assert abs(az + 90.0) < 2.0
    assert np.allclose(c.head_rotation[:, 0], [0.0, 1.0, 0.0], atol=0.03)  # the nose points along room +y
    ild_before = np.diff(level_db(before[:, 706 * 20 :]))[0]  # right minus left, dB
    ild_after = np.diff(level_db(after))[0]
    assert abs(ild_before) < 1.5 and ild_after > ild_before + 2.5  # the right ear is now the louder


def test_clock_blocks_and_events_line_up(kemar):
    c = Coupling.from_scene("room", rng=np.random.default_rng(1), hrtf=kemar, background=False)
    assert c.time_s == 0.0
    call = c.events.schedule_call(0.1)
    lengths, events = [], []
    for k in range(1, 26):
        events += c.advance()
        block = c.render()
        lengths.append(block.shape[1])
        assert block.shape[1] == block_length(k) and c.renderer.sample == frame_end_sample(k) == c.block_start
    assert set(lengths) == {705, 706} and sum(lengths) == frame_end_sample(25)
    assert c.data.time == pytest.approx(25 * 0.016)
    assert [(e.kind, e.sample, e.source, e.label) for e in events] == [("voice_call", call, "voice", "human_voice")]
    assert np.allclose(c.source_positions()["voice"], c.frame.to_room(c.view.site_position(names.PERSON_MOUTH_SITE)))


def test_sources_move_with_their_bodies(kemar):
    c = Coupling.from_scene("room", rng=np.random.default_rng(2), hrtf=kemar, background=False)
    c.events.schedule_call()
    c.step()
    first = c.source_positions()["voice"].copy()
    scenes.place_mocap(c.model, c.data, names.PERSON_ROOT_BODY, [3.0, 4.0, 0.0], yaw_deg=-90.0)
    c.step()
    moved = c.source_positions()["voice"]
    assert np.linalg.norm(moved - first) > 0.5
    assert np.allclose(moved, c.frame.to_room(c.view.site_position(names.PERSON_MOUTH_SITE)), atol=c.move_threshold_m)
    assert np.allclose(c.renderer.sources["voice"].position, moved)


def test_gearshift_source_follows_the_knob():
    model, data, _ = scenes.load_scene("cabin")
    c = Coupling(model, data, None, rng=np.random.default_rng(0))
    start = c.emitter_position("gearshift")
    dof = model.joint(names.GEARSHIFT_JOINT).dofadr[0]
    for _ in range(80):
        data.qfrc_applied[dof] = 10.0 * (30 * DEG - c.view.gearshift_angle()) - 0.3 * c.view.joint_velocity(names.GEARSHIFT_JOINT)
        c.advance()
    end = c.emitter_position("gearshift")
    assert c.view.gearshift_position() == "N"
    assert np.linalg.norm(end - start) > 0.1  # the knob, 0.29 m up the lever, swings 30 deg back toward D
    assert np.allclose(end, c.frame.to_room(c.view.site_position(names.GEARSHIFT_KNOB_SITE)))


def test_outside_horn_plays_inside_the_windscreen(kemar):
    c = Coupling.from_scene("cabin", rng=np.random.default_rng(3), hrtf=kemar, background=False, ego_noise=False)
    horn = c.frame.to_room(c.view.site_position(names.HORN_SITE))
    assert horn[0] > c.frame.dimensions[0]  # the grille is outside the cabin's air volume
    inside = c.emitter_position("horn")
    assert inside[0] == pytest.approx(c.frame.dimensions[0] - c.outside_margin_m)
    # On the straight line from the grille to the head: heard from the horn's own direction.
    to_horn, to_inside = horn - c.head_position, inside - c.head_position
    assert np.allclose(to_inside / np.linalg.norm(to_inside), to_horn / np.linalg.norm(to_horn), atol=1e-9)
    loud = np.random.default_rng(0).standard_normal(44100)  # unit RMS
    c.events.schedule_horn(0.0, signal=loud)
    c.step()
    sound = c._emitters["horn"].sounds[0]
    d = np.linalg.norm(horn - inside)
    expected = c.events.config.horn_db - c.events.config.transmission_loss_db - 20 * np.log10(max(d, 1.0))
    assert 20 * np.log10(sound.gain / 20e-6) == pytest.approx(expected)
    x = np.concatenate([c.step() for _ in range(30)], axis=1)
    # The same sound added to a renderer by hand, at that point and level, is as loud.
    ref = BinauralRenderer(kemar, c.renderer.room, rng=np.random.default_rng(9), background=False)
    ref.set_head_pose(c.head_position, c.head_rotation)
    ref.add_source("horn", loud, inside, level_db=expected, start=0)
    y = np.concatenate([ref.render_block() for _ in range(31)], axis=1)[:, -x.shape[1] :]
    assert np.allclose(level_db(x), level_db(y), atol=0.5)


def test_emitter_source_is_released_when_silent(kemar):
    c = Coupling.from_scene("cabin", rng=np.random.default_rng(4), hrtf=kemar, background=False, ego_noise=False)
    c.events.schedule_key_turn(0.0, signal=np.ones(2000))
    c.step()
    assert "ignition" in c.renderer.sources
    for _ in range(int((1.0 + 0.5) * 62.5)):
        c.step()
    assert "ignition" not in c.renderer.sources  # idle_release_s plus the cabin's short reverberation


def test_alarm_stops_on_its_sample(kemar):
    """Leaving R stops the looping alarm on the event's sample: after its 5 ms fade and the
    room's early reflections, the ears hear nothing of it. The alarm's part of the ear
    signals is isolated by rendering the same episode twice, the second time with the alarm
    20 dB SPL at 1 m (the renderer is linear; the gear change sounds the same in both)."""

    def episode(alarm_db):
        c = Coupling.from_scene("cabin", rng=np.random.default_rng(5), hrtf=kemar, background=False, ego_noise=False,
                                late=False, scene_config=scenes.CabinConfig(gear="R"), events_config=EventsConfig(alarm_db=alarm_db))
        stop, audio = None, []
        dof = c.model.joint(names.GEARSHIFT_JOINT).dofadr[0]
        for k in range(int(3.0 * 62.5)):
            if k > 30:
                c.data.qfrc_applied[dof] = 10.0 * (30 * DEG - c.view.gearshift_angle()) - 0.3 * c.view.joint_velocity(
                    names.GEARSHIFT_JOINT)
            stop = next((e.sample for e in c.advance() if e.kind == "alarm_stop"), stop)
            audio.append(c.render())
        return stop, np.concatenate(audio, axis=1)

    (stop, loud), (stop2, quiet) = episode(85.0), episode(20.0)
    assert stop == stop2
    alarm = (loud - quiet) / (1.0 - 10 ** ((20.0 - 85.0) / 20))
    assert np.max(np.abs(alarm[:, :stop])) > 0.05  # Pa: it was sounding
    silent_from = stop + int(np.ceil(0.005 * 44100)) + int(0.06 * 44100)  # fade, then 60 ms of early reflections
    assert np.max(np.abs(alarm[:, silent_from:])) < 1e-6 * np.max(np.abs(alarm[:, :stop]))


def test_ego_noise_follows_the_arms(kemar):
    c = Coupling.from_scene("cabin", rng=np.random.default_rng(6), hrtf=kemar, background=False)
    assert isinstance(c.ego_noise, MotorEgoNoise)
    settle(c, 1.0)
    rest = c.ego_noise.level_db
    shoulder = c.data.actuator(names.arm_joints("right")[0])
    levels = []
    for amplitude in (0.2, 0.8):
        peak = -np.inf
        start = float(shoulder.ctrl[0])
        for k in range(40):
            shoulder.ctrl[0] = start + amplitude * np.sin(2 * np.pi * 1.5 * k / 62.5)
            c.advance()
            peak = max(peak, c.ego_noise.level_db)
        shoulder.ctrl[0] = start
        settle(c, 1.0)
        levels.append(peak)
    assert rest < levels[0] < levels[1]  # faster (larger) swings are louder
    assert levels[1] - rest > 10.0


def test_coupling_errors(cabin, kemar):
    model, data, _ = cabin
    with pytest.raises(ConfigError, match="not the scene's air volume"):
        Coupling(model, data, BinauralRenderer(kemar, room_preset("lab"), rng=np.random.default_rng(0)), rng=np.random.default_rng(0))
    r = BinauralRenderer(kemar, scenes.acoustic_room(model), rng=np.random.default_rng(0), background=False)
    c = Coupling(model, mujoco.MjData(model), r, rng=np.random.default_rng(0))  # a fresh MjData is forwarded
    with pytest.raises(ConfigError, match="must follow one advance"):
        c.render()
    r.ego_noise = MotorEgoNoise(np.ones(1), np.ones(1))
    with pytest.raises(ConfigError, match="from_view"):
        Coupling(model, data, r, rng=np.random.default_rng(0))
    r.ego_noise = None
    r.render_block(100)
    with pytest.raises(ConfigError, match="frame boundary"):
        Coupling(model, data, r, rng=np.random.default_rng(0))
    spec = scenes.build_scene("cabin")
    spec.option.timestep = 0.003
    odd = spec.compile()
    with pytest.raises(ConfigError, match="must divide"):
        Coupling(odd, mujoco.MjData(odd), None, rng=np.random.default_rng(0))
    with pytest.raises(ConfigError, match="no renderer"):
        Coupling(model, mujoco.MjData(model), None, rng=np.random.default_rng(0)).render()
    with pytest.raises(ConfigError, match="move_threshold_m"):
        Coupling(model, data, None, rng=np.random.default_rng(0), move_threshold_m=1.0)
    with pytest.raises(ConfigError, match="numpy.random.Generator"):
        Coupling.from_scene("cabin", rng=0)
    with pytest.raises(ConfigError, match="unknown scene"):
        Coupling.from_scene("garage", rng=np.random.default_rng(0))


def test_view_body_poses_and_camera_pose_are_copies(cabin):
    model, data, _ = cabin
    mujoco.mj_forward(model, data)
    v = WorldView(model, data)
    pos, quat = v.body_poses()
    assert pos.shape == (model.nbody, 3) and quat.shape == (model.nbody, 4)
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-9)
    pos[:] = 99.0
    assert not np.any(data.xpos == 99.0)
    origin, rot = v.camera_pose(names.EYE_CAMERAS[1])
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-9)
    # The eye camera sits on the head, within 0.15 m of the ears' midpoint.
    left, right = v.ear_poses()
    assert np.linalg.norm(origin - (left + right) / 2) < 0.15
    with pytest.raises(ConfigError, match="no camera"):
        v.camera_pose("no_such_camera")
