"""The Gymnasium hearing tasks: API conformance, the spec docstrings, determinism, vector envs,
the per-step clock, ground truth and the geometric field-of-view check.

Every env here uses the ``fast`` auditory profile (small networks; trained once per test
session into the session's model cache by the first env)."""

import ast
import inspect
import re
import sys

import numpy as np
import pytest


import gymnasium as gym
from gymnasium.utils.env_checker import check_env

import tasks
from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scenes
from policies import make_policy
from tasks.actions import action_layout
from tasks.base import CONTROL_DT
from tasks.call_response import CallResponseEnv
from tasks.levers import lever_arm_angles
from tasks.parking_brake import ParkingBrakeEnv
from tasks.reverse_alarm import ReverseAlarmEnv

IDS = [v[0] for v in tasks.TASKS.values()]
CLASSES = [ReverseAlarmEnv, ParkingBrakeEnv, CallResponseEnv]


_ARG = re.compile(r"^\s*``(\w+)`` \((.+?), default (.+?)\):", re.MULTILINE)


@pytest.mark.parametrize("cls", CLASSES)
def test_docstring_is_the_spec_and_its_defaults_match_the_signature(cls):
    doc = inspect.getdoc(cls)
    for section in ("Description", "Action Space", "Observation Space", "Rewards", "Starting State", "Episode End", "Arguments"):
        assert f"\n{section}\n" in f"\n{doc}", f"{cls.__name__} docstring lacks the {section} section"
    documented = {m.group(1): m.group(3) for m in _ARG.finditer(doc.split("\nArguments\n")[1])}
    params = {n: p.default for n, p in inspect.signature(cls.__init__).parameters.items() if n != "self"}
    assert set(documented) == set(params), f"documented {sorted(documented)} vs signature {sorted(params)}"
    for name, text in documented.items():
        assert ast.literal_eval(text) == params[name], f"{cls.__name__}.{name}: docstring says {text}, signature {params[name]!r}"


@pytest.mark.parametrize("cls", CLASSES)
def test_docstring_lists_every_observation_and_action(cls):
    env = cls(profile="fast", audio_obs=True, spectra_obs=True, image_obs=True)
    doc = inspect.getdoc(cls)
    for key in env.observation_space.spaces:
        assert re.search(rf"\b{key}\b", doc), f"observation {key!r} is not in the docstring"
    # The Observation Space table's keys and shapes are the space's (D: the grid, H, W: image_size).
    table = doc.split("\nObservation Space\n")[1].split("\nRewards\n")[0]
    rows = dict(re.findall(r"^(\w+) +(\([^)]*\)) ", table, re.MULTILINE))
    sizes = {"D": len(env.pipeline.grid), "H": env.image_size[0], "W": env.image_size[1]}
    shapes = {k: tuple(sizes[v] if v in sizes else int(v) for v in re.findall(r"\w+", shape)) for k, shape in rows.items()}
    assert shapes == {k: space.shape for k, space in env.observation_space.spaces.items()}
    for name in env.layout.names:
        assert name in doc or name.split("_")[0] in ("left", "right"), f"action {name!r} is not in the docstring"
    assert env.action_space.shape == (16,)
    env.close()


@pytest.mark.parametrize("cls", CLASSES)
def test_docstring_action_table_is_the_actuators_ranges(cls):
    """The spec's action table (the same in every task: tests/spec_docs.py) against the model's control ranges."""
    doc = inspect.getdoc(cls)
    layout = action_layout(cls.scene_name)
    rows = re.findall(r"^(\d+) +(\w+)[^\n]*? (-?\d+) \.\. (-?\d+) +(deg|rad/s|> 0 hold, <= 0 open)$", doc, re.MULTILINE)
    assert [int(r[0]) for r in rows] == [*range(9), 14, 15], rows
    for idx, name, lo, hi, unit in rows:
        ch = layout.channels[int(idx)]
        to_doc = np.rad2deg if unit == "deg" else float
        assert ch.name == name and (round(to_doc(ch.low)), round(to_doc(ch.high))) == (int(lo), int(hi)), (ch, lo, hi)
    assert re.search(r"^9-13 +right arm, same joints +same +deg$", doc, re.MULTILINE)
    for suffix in names.ARM_JOINT_SUFFIXES:
        left, right = (layout.channels[layout.index(f"{side}_{suffix}")] for side in ("left", "right"))
        assert (left.low, left.high) == (right.low, right.high)
    assert f"``Box(-1, 1, ({len(layout)},), float32)``" in doc


def test_docstring_is_written_out_and_holds_the_shared_spec_word_for_word():
    """The specification is text in the source (no template expanded at import), and the
    parts every task shares are those of ``tests/spec_docs.py`` (the reward weights, the skill
    tables, the default time limit), so neither drifts from the code or from the other tasks."""
    import spec_docs

    for cls in CLASSES:
        source = inspect.getsource(cls)
        assert not re.search(r"^\s*\{\w+\}\s*$", cls.__doc__, re.MULTILINE), cls
        assert cls.__doc__ in source, f"{cls.__name__}'s docstring is not written in its source"
        for name, text in spec_docs.parts(cls).items():
            assert spec_docs.indented(text) in cls.__doc__, f"{cls.__name__}'s docstring differs from the shared {name}"
    with pytest.raises(ConfigError, match="2 cells"):
        spec_docs.rst_table(("key", "meaning"), [("a", "b", "c")])


def _rollout(env, policy_name, seed, steps):
    policy = make_policy(policy_name, env)
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info)
    trace = [obs]
    events = []
    for _ in range(steps):
        obs, _reward, terminated, truncated, info = env.step(policy.act(obs, info))
        trace.append(obs)
        events += info["events"]
        if terminated or truncated:
            break
    return trace, events, info


def test_same_seed_same_episode_bit_for_bit():
    env = ReverseAlarmEnv(profile="fast", audio_obs=True)
    a, ea, _ia = _rollout(env, "scripted", 7, 80)
    b, eb, _ib = _rollout(env, "scripted", 7, 80)
    c, _ec, _ = _rollout(env, "scripted", 8, 80)
    assert len(a) == len(b) and ea == eb
    for x, y in zip(a, b):
        for key in x:
            assert np.array_equal(x[key], y[key]), key
    assert not all(np.array_equal(x["audio"], y["audio"]) for x, y in zip(a, c))  # another seed, other sounds
    env.close()


def test_one_percept_per_step_on_the_clock():
    from acoustic_sim.frames import frame_end_sample

    env = ParkingBrakeEnv(profile="fast", audio_obs=True)
    obs, info = env.reset(seed=0)
    for _ in range(5):
        obs, *_ , info = env.step(env.layout.home())
        p = env.last_percept
        assert p.frame == env.coupling.frame_index  # the ear frame that ends with this step's block
        assert p.time_s == pytest.approx(frame_end_sample(p.frame) / 44100)
        assert env.last_audio.shape[1] in (705, 706) and obs["audio"].shape == (2, 706)
        assert info["time_s"] == pytest.approx(p.time_s)
    env.close()


def test_optional_observations_and_rgb_render():
    # A fresh interpreter: MuJoCo's OpenGL backend is fixed when mujoco is first imported, and
    # tasks.base picks an offscreen one (EGL or OSMesa) only if it comes first.
    code = """
import json
import numpy as np
from tasks.call_response import CallResponseEnv
env = CallResponseEnv(profile="fast", render_mode="rgb_array", spectra_obs=True, image_obs=True, image_size=(48, 64))
obs, _ = env.reset(seed=2)
obs, *_ = env.step(env.layout.home())
frame = env.render()
print(json.dumps({"image": [list(obs["image"].shape), str(obs["image"].dtype), float(obs["image"].std())],
                  "spectra": [list(obs["spectra"].shape), float(obs["spectra"].min()), float(obs["spectra"].sum())],
                  "base": list(obs["base"].shape), "frame": [list(frame.shape), str(frame.dtype), float(frame.std())]}))
env.close()
"""
    import json
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=300, capture_output=True, text=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["image"][:2] == [[48, 64, 3], "uint8"] and r["image"][2] > 1.0
    assert r["spectra"][0] == [2, 1025] and r["spectra"][1] >= 0 and r["spectra"][2] > 0
    assert r["base"] == [3]
    assert r["frame"][:2] == [[480, 640, 3], "uint8"] and r["frame"][2] > 1.0


@pytest.mark.parametrize("vector", ["sync", "async"])
def test_vector_envs(vector):
    cls = gym.vector.SyncVectorEnv if vector == "sync" else gym.vector.AsyncVectorEnv
    envs = cls([lambda: gym.make("acoustic_sim/ParkingBrake-v0", profile="fast") for _ in range(2)])
    try:
        obs, _ = envs.reset(seed=[3, 4])
        assert obs["class_prob"].shape == (2, 6) and obs["existence"].shape[0] == 2
        for _ in range(4):
            obs, reward, _terminated, _truncated, _info = envs.step(envs.action_space.sample())
        assert reward.shape == (2,) and obs["joint_pos"].shape == (2, 14)
    finally:
        envs.close()


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec(mode):
    envs = gym.make_vec("acoustic_sim/ReverseAlarm-v0", num_envs=2, vectorization_mode=mode, profile="fast")
    try:
        obs, _ = envs.reset(seed=5)
        assert obs["class_prob"].shape == (2, 6) and obs["class_dir"].shape == (2, 18)
        envs.action_space.seed(5)
        obs, reward, terminated, truncated, _ = envs.step(envs.action_space.sample())
        assert reward.shape == (2,) and terminated.shape == (2,) and obs["joint_pos"].shape == (2, 14)
    finally:
        envs.close()


def test_import_acoustic_sim_registers_the_ids_with_their_time_limits():
    import json
    import subprocess

    code = ("import json, sys, acoustic_sim, gymnasium; print(json.dumps([[gymnasium.spec(i).max_episode_steps "
            f"for i in {IDS!r}], 'tasks' in sys.modules, 'mujoco' in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    steps, tasks_loaded, mujoco_loaded = json.loads(out.stdout.strip().splitlines()[-1])
    # The TimeLimit is the env's own default limit, in control steps; nothing heavy is imported.
    assert steps == [round(cls.default_max_episode_s / CONTROL_DT) for cls in CLASSES]
    assert not tasks_loaded and not mujoco_loaded
    env = gym.make(IDS[1], profile="fast")
    try:
        assert isinstance(env, gym.wrappers.TimeLimit) or any(
            isinstance(w, gym.wrappers.TimeLimit) for w in _wrappers(env))
    finally:
        env.close()


def _wrappers(env):
    while isinstance(env, gym.Wrapper):
        yield env
        env = env.env


def test_oracle_reverse_alarm_and_ground_truth():
    env = ReverseAlarmEnv(profile="fast", distractors=False)
    _trace, events, info = _rollout(env, "oracle", 0, 400)
    assert info["outcome"] == "success" and info["success"] and not info["false_release"]
    kinds = [e["kind"] for e in events]
    assert "alarm_start" in kinds and info["gear"] == "R"
    assert 0.0 <= info["reaction_s"] <= 0.05  # the step after the alarm's block
    alarm = [s for s in info["sounding"] if s["source"] == "alarm"]
    assert alarm and abs(alarm[0]["azimuth_deg"]) < 10.0  # in front of the head
    assert info["labels"][1] == 1  # reverse_alarm is sounding
    env.close()


def test_letting_go_early_is_a_false_release():
    env = ParkingBrakeEnv(profile="fast", distractors=False)
    env.reset(seed=0)
    a = env.layout.action({"grasp_right": -1.0})
    _obs, reward, terminated, _truncated, info = env.step(a)
    assert terminated and reward == -1.0 and info["outcome"] == "early" and info["false_release"]
    env.close()


def test_call_response_field_of_view_and_occlusion():
    env = CallResponseEnv(profile="fast", distractors=False)
    env.reset(seed=0)
    assert not env.person_in_view()[0]  # the person starts out of view
    cam = env.data.cam(names.EYE_CAMERAS[1])
    forward = -cam.xmat.reshape(3, 3)[:, 2]
    spot = cam.xpos + 2.0 * forward
    scenes.place_mocap(env.model, env.data, names.PERSON_ROOT_BODY, [spot[0], spot[1], 0.0], 0.0)
    scenes.place_mocap(env.model, env.data, names.LOUDSPEAKER_BODY, [5.5, 0.5, 0.0], 0.0)
    import mujoco

    mujoco.mj_forward(env.model, env.data)
    head = env.view.body_pose(names.PERSON_HEAD_BODY)[0]
    env_cam = env.data.cam(names.EYE_CAMERAS[1]).xpos
    visible, (u, v) = env.person_in_view()
    assert visible and abs(u) < 0.3, (visible, u, v, head, env_cam)
    # the loudspeaker between the eye and the head hides it
    mid = cam.xpos + 1.0 * forward
    speaker_top = 1.17  # the cone's height above the floor is about the eyes'
    scenes.place_mocap(env.model, env.data, names.LOUDSPEAKER_BODY, [mid[0], mid[1], head[2] - speaker_top - 0.05], 0.0)
    mujoco.mj_forward(env.model, env.data)
    assert not env.person_in_view()[0]
    env.close()


def test_bad_arguments_are_config_errors():
    with pytest.raises(ConfigError, match="profile"):
        ReverseAlarmEnv(profile="huge")
    with pytest.raises(ConfigError, match="max_episode_s"):
        ReverseAlarmEnv(profile="fast", max_episode_s=-1.0)
    with pytest.raises(ConfigError, match="required_teeth"):
        ParkingBrakeEnv(profile="fast", required_teeth=9)
    with pytest.raises(ConfigError, match="success_window_s"):
        ParkingBrakeEnv(profile="fast", success_window_s=0.0)
    with pytest.raises(ConfigError, match="release_timeout_s"):
        ReverseAlarmEnv(profile="fast", release_timeout_s=float("nan"))
    with pytest.raises(ConfigError, match="call_interval_s"):
        CallResponseEnv(profile="fast", call_interval_s=(1.0, 0.5))
    with pytest.raises(ConfigError, match="render_mode"):
        ReverseAlarmEnv(profile="fast", render_mode="human")
    env = ReverseAlarmEnv(profile="fast")
    with pytest.raises(ConfigError, match="reset"):
        env.step(env.layout.home())
    env.reset(seed=0)
    with pytest.raises(ConfigError, match="16 finite"):
        env.step(np.zeros(3))
    with pytest.raises(ConfigError, match="no action channel"):
        env.layout.action({"tail": 1.0})
    env.close()


def test_taught_lever_motions_reach_along_the_arcs():
    from tasks.base import lever_motion

    for side, needed in (("left", 30.0), ("right", 45.0)):
        deg, arm = lever_motion(side)
        assert deg[0] == 0.0 and deg[-1] >= needed and arm.shape == (deg.size, 5)
    with pytest.raises(ConfigError, match="side"):
        lever_motion("middle")


# -- sounds placed anywhere ------------------------------------------------------------------------


def _quiet_room():
    """The room scene's coupling with nothing but the task's sounds (no background, no ego-noise)."""
    from acoustic_sim.world.coupling import Coupling
    from tasks.task_sounds import Soundscape

    c = Coupling.from_scene("room", rng=np.random.default_rng(0), ego_noise=False, background=False)
    return c, Soundscape(c)


def test_a_scheduled_sound_arrives_from_its_direction_at_its_sample():
    from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND

    c, sc = _quiet_room()
    head, rot = c.head_position.copy(), c.head_rotation.copy()
    burst = np.random.default_rng(1).standard_normal(round(0.15 * SAMPLE_RATE))
    left = sc.schedule_sound("left", "car_horn", burst, head + 1.0 * rot[:, 1], c.time_s + 0.1003, 80.0)
    right_world = c.frame.to_world(head - 1.0 * rot[:, 1])  # 90 deg right, given in MuJoCo's world frame
    right = sc.schedule_sound("right", "key_turning", burst, right_world, c.time_s + 0.9007, 80.0, frame="world")
    np.testing.assert_allclose(right.position, head - rot[:, 1], atol=1e-9)
    first, blocks, records, starts = c.renderer.sample, [], [], {}
    for _ in range(90):  # 1.44 s
        new = sc.begin_block(c.advance())
        starts.update({r["source"]: c.renderer.sources[r["source"]].start for r in new})
        records += new
        blocks.append(c.render())
        sc.end_block()
    y = np.concatenate(blocks, axis=1)
    assert y.shape[1] == c.renderer.sample - first
    assert starts == {"task/left": left.start, "task/right": right.start}
    assert set(c.renderer.sources) == {"task/right"}  # the left one is over, reverberation (1 s) included
    assert [(r["source"], r["time_s"]) for r in records] == [("task/left", left.start / SAMPLE_RATE), ("task/right", right.start / SAMPLE_RATE)]
    delay = round(1.0 / SPEED_OF_SOUND * SAMPLE_RATE)  # 1 m from the head centre
    for snd, near, far in ((left, 0, 1), (right, 1, 0)):
        s0 = snd.start - first
        window = y[:, s0 : s0 + round(0.2 * SAMPLE_RATE)]
        peak = np.abs(window).max()
        assert np.abs(y[:, s0 - 2000 : s0]).max() < 1e-3 * peak  # silence until the scheduled sample
        onset, onset_far = (int(np.argmax(np.abs(window[e]) > 0.02 * peak)) for e in (near, far))
        assert -20 <= onset - delay <= 5, (snd.name, onset, delay)  # the direct sound, 1 m away
        assert onset_far > onset + 10, (snd.name, onset, onset_far)  # the near ear hears it first
        direct = window[:, onset - 10 : onset + 220]  # the first 5 ms: before the first reflection
        ild = 10 * np.log10(np.sum(direct[near] ** 2) / np.sum(direct[far] ** 2))
        assert ild > 10.0, (snd.name, ild)  # left source: louder at the left ear; right: at the right


def test_sounds_outside_the_room_play_through_the_wall():
    c, sc = _quiet_room()
    head = c.head_position
    s = sc.schedule_sound("car", "reverse_alarm", np.ones(100), [-3.0, head[1], 1.0], c.time_s + 0.5, 100.0, outside=True)
    margin, loss = c.outside_margin_m, c.events.config.transmission_loss_db
    entry = head + (margin - head[0]) / (-3.0 - head[0]) * (np.array([-3.0, head[1], 1.0]) - head)
    np.testing.assert_allclose(s.position, entry)  # where the straight path to the head enters
    assert s.position[0] == pytest.approx(margin)
    assert s.level_db == pytest.approx(100.0 - loss - 20 * np.log10(np.linalg.norm(np.array([-3.0, head[1], 1.0]) - entry)))


def test_schedule_sound_errors():
    from acoustic_sim.world.coupling import Coupling
    from tasks.task_sounds import Soundscape

    c, sc = _quiet_room()
    head, t = c.head_position, c.time_s + 0.2
    ok = {"signal": np.ones(10), "position": head + [1.0, 0.0, 0.0], "t": t, "level_db": 70.0}
    sc.schedule_sound("a", "car_horn", **ok)
    for change, match in (
        ({"name": "a"}, "exists already"),
        ({"name": ""}, "non-empty string"),
        ({"label": "trumpet"}, "unknown sound class"),
        ({"signal": np.ones((2, 5))}, "1-D"),
        ({"signal": [np.nan]}, "finite"),
        ({"level_db": 200.0}, "level_db"),
        ({"t": c.time_s - 0.1}, "in the past"),
        ({"t": float("nan")}, "finite time"),
        ({"frame": "car"}, "frame"),
        ({"position": [1.0, 2.0]}, "3 finite"),
        ({"position": [9.0, 1.0, 1.0]}, "not inside room"),
        ({"outside": True}, "inside the room"),
        ({"position": [-300.0, 1.0, 1.0], "outside": True, "level_db": 30.0}, "too far or too quiet"),
    ):
        args = {"name": "b", "label": "car_horn", **ok, **change}
        with pytest.raises(ConfigError, match=match):
            sc.schedule_sound(**args)
    with pytest.raises(ConfigError, match="linger_s"):
        Soundscape(c, linger_s=-1.0)
    model, data = c.model, c.data
    with pytest.raises(ConfigError, match="renderer"):
        Soundscape(Coupling(model, data, None, rng=np.random.default_rng(0)))


def test_env_schedule_sound_ground_truth():
    env = ReverseAlarmEnv(profile="fast", distractors=False)
    with pytest.raises(ConfigError, match="reset"):
        env.schedule_sound("probe", "car_horn", np.ones(10), [1.0, 1.0, 0.8], 0.1, 70.0)
    env.reset(seed=0)
    c = env.coupling
    point = c.head_position + 0.3 * c.head_rotation[:, 1]  # 90 deg left, inside the cabin
    snd = env.schedule_sound("probe", "car_horn", np.random.default_rng(0).standard_normal(4410), point, 0.1, 75.0)
    assert snd.start == round((env.start_s + 0.1) * 44100) and env.task_sounds == [snd]
    with pytest.raises(ConfigError, match="start_s"):
        env.schedule_sound("late", "car_horn", np.ones(10), point, float("inf"), 70.0)
    with pytest.raises(ConfigError, match="in the past"):
        env.schedule_sound("late", "car_horn", np.ones(10), point, -0.5, 70.0)
    hold = env.layout.action({**env.layout.arm("left", lever_arm_angles("left", 0.0)), "grasp_left": 1.0})
    seen = []
    for _ in range(12):
        _obs, _r, terminated, _t, info = env.step(hold)
        seen += [e for e in info["events"] if e["source"] == "task/probe"]
        probe = [s for s in info["sounding"] if s["source"] == "task/probe"]
        if probe:
            break
    assert not terminated
    assert seen == [{"kind": "distractor", "label": "car_horn", "source": "task/probe", "time_s": snd.start / 44100, "detail": ""}]
    assert probe[0]["label"] == "car_horn" and abs(probe[0]["azimuth_deg"] - 90.0) < 3.0
    assert info["labels"][0] == 1  # car_horn sounding
    env.close()
