"""The Gymnasium hearing tasks: API conformance, the spec docstrings, determinism, vector envs,
the per-step clock, ground truth and the geometric field-of-view check.

Every env here uses the ``fast`` auditory profile (small networks; trained once per test
session into the session's model cache by the first env)."""

import ast
import inspect
import re
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tasks/ and policies/ beside acoustic_sim/

import gymnasium as gym
from gymnasium.utils.env_checker import check_env

import tasks
from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scene
from policies import make_policy
from tasks.call_response import CallResponseEnv
from tasks.parking_brake import ParkingBrakeEnv
from tasks.reverse_alarm import ReverseAlarmEnv

IDS = [v[0] for v in tasks.TASKS.values()]
CLASSES = [ReverseAlarmEnv, ParkingBrakeEnv, CallResponseEnv]


@pytest.mark.parametrize("env_id", IDS)
def test_registered_and_check_env_passes(env_id):
    env = gym.make(env_id, profile="fast")
    try:
        check_env(env.unwrapped, skip_render_check=True)
        obs, _ = env.reset(seed=1)
        assert env.observation_space.contains(obs)
        for _ in range(3):
            obs, reward, _terminated, _truncated, _info = env.step(env.action_space.sample())
            assert env.observation_space.contains(obs) and isinstance(reward, float)
    finally:
        env.close()


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
    if cls is ParkingBrakeEnv:  # refers to ReverseAlarm's tables for the shared parts
        doc += inspect.getdoc(ReverseAlarmEnv)
    for key in env.observation_space.spaces:
        assert re.search(rf"\b{key}\b", doc), f"observation {key!r} is not in the docstring"
    for name in env.layout.names:
        assert name in doc or name.split("_")[0] in ("left", "right"), f"action {name!r} is not in the docstring"
    assert env.action_space.shape == (16,)
    env.close()


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
import sys, json
sys.path.insert(0, sys.argv[1])
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
    root = str(Path(__file__).resolve().parents[1])
    out = subprocess.run([sys.executable, "-c", code, root], check=True, env=env, timeout=300, capture_output=True, text=True)
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
    scene.place_mocap(env.model, env.data, names.PERSON_ROOT_BODY, [spot[0], spot[1], 0.0], 0.0)
    scene.place_mocap(env.model, env.data, names.LOUDSPEAKER_BODY, [5.5, 0.5, 0.0], 0.0)
    import mujoco

    mujoco.mj_forward(env.model, env.data)
    head = env.view.body_pose(names.PERSON_HEAD_BODY)[0]
    env_cam = env.data.cam(names.EYE_CAMERAS[1]).xpos
    visible, (u, v) = env.person_in_view()
    assert visible and abs(u) < 0.3, (visible, u, v, head, env_cam)
    # the loudspeaker between the eye and the head hides it
    mid = cam.xpos + 1.0 * forward
    speaker_top = 1.17  # the cone's height above the floor is about the eyes'
    scene.place_mocap(env.model, env.data, names.LOUDSPEAKER_BODY, [mid[0], mid[1], head[2] - speaker_top - 0.05], 0.0)
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
