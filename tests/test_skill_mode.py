"""The learner's interface: the skill action mode, the shaped reward, and both env checkers."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import tasks
from acoustic_sim.errors import ConfigError
from tasks.base import CONTROL_DT
from tasks.call_response import CallResponseEnv
from tasks.reverse_alarm import PAPER_CAR, ReverseAlarmEnv
from tasks.skills import RELEASE_STEPS, LeverSkill, TurnSkill

IDS = [v[0] for v in tasks.TASKS.values()]


@pytest.mark.parametrize("action_mode", ["joints", "skill"])
@pytest.mark.parametrize("env_id", IDS)
def test_registered_and_both_checkers_pass(env_id, action_mode):
    """Gymnasium's and stable-baselines3's checkers, with every warning an error (the
    optional per-ear ``audio`` and ``spectra``, (2, N), are checked by Gymnasium's only:
    stable-baselines3 asks for a custom feature extractor for them, and says so)."""
    env = gym.make(env_id, profile="fast", action_mode=action_mode, reward_mode="shaped")
    spectra = gym.make(env_id, profile="fast", action_mode=action_mode, spectra_obs=True, audio_obs=True)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env.unwrapped, skip_render_check=True)
            sb3_check_env(env.unwrapped, warn=True)
            check_env(spectra.unwrapped, skip_render_check=True)
        assert env.action_space.shape == ((2,) if action_mode == "skill" else (16,))
        obs, _ = env.reset(seed=1)
        assert env.observation_space.contains(obs)
        for _ in range(3):
            obs, reward, _terminated, _truncated, _info = env.step(env.action_space.sample())
            assert env.observation_space.contains(obs) and isinstance(reward, float)
    finally:
        env.close()
        spectra.close()


@pytest.mark.parametrize("env_id", IDS)
def test_skill_zero_action_runs_to_the_limit(env_id):
    """Nothing lets go and nothing moves: the episode is truncated at the env's own limit (in the
    room it ends ``too_late`` when the response window closes: nobody was turned to)."""
    env = gym.make(env_id, profile="fast", action_mode="skill")
    room = "CallResponse" in env_id
    try:
        obs, _ = env.reset(seed=7)
        start = np.array(obs["joint_pos"])
        limit = env.unwrapped.max_episode_steps
        for step in range(1, limit + 1):
            obs, _, terminated, truncated, info = env.step(np.zeros(2, np.float32))
            assert not terminated or (room and info["outcome"] == "too_late"), (step, info["outcome"])
            if truncated or terminated:
                break
        if room:
            u = env.unwrapped
            assert info["outcome"] == "too_late" and u.time_s - info["target_onset_s"] >= u.response_window_s
        else:
            assert step == limit and info["outcome"] == "timeout"
            assert info["reward_outcome"] == -1.0  # keeping still to the limit fails the cabin's task
        if "holding" in info:
            assert info["holding"]
        # the servos hold the start pose (within 1 deg: what the lever's spring and the base's wobble move)
        np.testing.assert_allclose(obs["joint_pos"], start, atol=math.radians(1.0))
    finally:
        env.close()


def test_release_must_be_held():
    """Release above the level for RELEASE_STEPS - 1 steps, then not: the hand holds; for
    RELEASE_STEPS steps: it lets go (before any alarm: a false release)."""
    env = ReverseAlarmEnv(profile="fast", action_mode="skill")
    env.reset(seed=3)
    for _ in range(3):
        for _ in range(RELEASE_STEPS - 1):
            _, _, terminated, _, info = env.step(np.array([0.0, 1.0], np.float32))
        _, _, terminated, _, info = env.step(np.array([0.0, 0.0], np.float32))
        assert not terminated and info["holding"]
    for k in range(RELEASE_STEPS):
        _, _, terminated, _, info = env.step(np.array([0.0, 0.9], np.float32))
        assert terminated == (k == RELEASE_STEPS - 1)
    assert info["outcome"] == "early" and info["false_release"] and not info["holding"]


def test_lever_rate_moves_the_lever_along_its_taught_motion():
    env = ReverseAlarmEnv(profile="fast", action_mode="skill", **PAPER_CAR)
    env.reset(seed=4)
    seconds = 0.5
    for _ in range(round(seconds / CONTROL_DT)):
        _, _, terminated, _, info = env.step(np.array([1.0, -1.0], np.float32))
        assert not terminated
    target = LeverSkill.max_rate_deg_s * seconds
    for _ in range(round(0.3 / CONTROL_DT)):  # hold still: the lever settles on the commanded angle
        _, _, _, _, info = env.step(np.zeros(2, np.float32))
    assert info["gear_deg"] == pytest.approx(target, abs=2.0), info["gear_deg"]


def test_turn_skill_turns_the_neck_and_the_wheelchair():
    env = CallResponseEnv(profile="fast", action_mode="skill", distractors=False)
    obs, _ = env.reset(seed=5)
    for _ in range(round(0.25 / CONTROL_DT)):  # neck only: 22.5 deg left
        obs, *_ = env.step(np.array([1.0, 0.0], np.float32))
    for _ in range(round(0.5 / CONTROL_DT)):  # wheelchair only: 45 deg right
        obs, *_ = env.step(np.array([0.0, -1.0], np.float32))
    for _ in range(round(0.5 / CONTROL_DT)):
        obs, *_ = env.step(np.zeros(2, np.float32))
    assert math.degrees(obs["joint_pos"][0]) == pytest.approx(TurnSkill.max_neck_deg_s * 0.25, abs=2.0)
    assert math.degrees(obs["base"][0]) == pytest.approx(-TurnSkill.max_turn_deg_s * 0.5, abs=5.0)


def run(env, actions, seed):
    env.reset(seed=seed)
    rewards, infos = [], []
    for a in actions:
        _, r, terminated, truncated, info = env.step(a)
        rewards.append(r)
        infos.append(info)
        if terminated or truncated:
            break
    return rewards, infos


def test_shaped_reward_is_the_sum_of_its_terms_and_ranks_success_first():
    """Each step's shaped reward is the sum of info's reward_* terms (the sparse one is
    reward_outcome); a success's return is above any failure's: a push into R that lets
    go at the alarm against a push past R and a release before the alarm."""
    env = ReverseAlarmEnv(profile="fast", action_mode="skill", reward_mode="shaped", **PAPER_CAR)
    returns = {}
    plans = {"early": [np.array([1.0, 0.0], np.float32)] * 20 + [np.array([0.0, 1.0], np.float32)] * RELEASE_STEPS,
             "past_reverse": [np.array([1.0, 0.0], np.float32)] * 200}
    for name, plan in plans.items():
        rewards, infos = run(env, plan, seed=11)
        for r, info in zip(rewards, infos):
            assert r == pytest.approx(sum(v for k, v in info.items() if k.startswith("reward_")), abs=1e-12)
        assert infos[-1]["outcome"] == name, infos[-1]["outcome"]
        returns[name] = sum(rewards)
    # the success: push at 8 deg/s until the alarm, then release at once
    env.reset(seed=11)
    total, onset = 0.0, None
    for _ in range(400):
        a = np.array([0.4, 1.0 if onset is not None else 0.0], np.float32)
        _, r, terminated, truncated, info = env.step(a)
        total += r
        onset = onset or info["target_onset_s"]
        if terminated or truncated:
            break
    assert info["outcome"] == "success", info["outcome"]
    assert total >= 1.0 > max(returns.values()) and max(returns.values()) <= -0.7 + 1e-9, (total, returns)
    sparse = ReverseAlarmEnv(profile="fast", action_mode="skill", **PAPER_CAR)
    rewards, infos = run(sparse, plans["early"], seed=11)
    assert rewards == [info["reward_outcome"] for info in infos] and rewards[-1] == -1.0


def test_skill_episodes_repeat_bit_for_bit():
    env = CallResponseEnv(profile="fast", action_mode="skill", reward_mode="shaped")
    plan = [np.array([np.sin(k / 9.0), 0.5], np.float32) for k in range(60)]
    a = run(env, plan, seed=21)
    b = run(env, plan, seed=21)
    assert a[0] == b[0]
    assert [i["person_bearing_deg"] for i in a[1]] == [i["person_bearing_deg"] for i in b[1]]


def test_bad_modes_are_refused():
    with pytest.raises(ConfigError, match="action_mode"):
        ReverseAlarmEnv(profile="fast", action_mode="torques")
    with pytest.raises(ConfigError, match="reward_mode"):
        ReverseAlarmEnv(profile="fast", reward_mode="dense")
    env = ReverseAlarmEnv(profile="fast", action_mode="skill")
    env.reset(seed=0)
    with pytest.raises(ConfigError, match=r"2 finite numbers .* \(skill mode\)"):
        env.step(np.zeros(16, np.float32))


def test_readme_gymnasium_example_runs(capsys):
    """The README's Gymnasium example, as printed there, runs an episode to its end."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    start = text.index("```python", text.index("## Gymnasium tasks")) + len("```python\n")
    code = text[start : text.index("```", start)]
    exec(compile(code, "README.md (Gymnasium tasks)", "exec"), {})
    outcome = capsys.readouterr().out.split()[0]
    assert outcome in {"success", "early", "late", "not_in_reverse", "past_reverse", "no_release", "timeout"}


class SkillPusher:
    """A skill-mode policy for ``run --policy test_skill_mode:SkillPusher``: push at 8 deg/s,
    let go once the reverse alarm is heard (the README example's rule)."""

    def __init__(self, env) -> None:
        self.env = env

    def reset(self, obs, info, seed=None) -> None:
        pass

    def act(self, obs, info) -> np.ndarray:
        return np.array([0.4, 1.0 if obs["class_prob"][1] > 0.5 else -1.0], np.float32)


def test_run_takes_the_modes_for_a_policy_written_for_them(tmp_path):
    import json

    from acoustic_sim.cli import main

    assert main(["run", "reverse-alarm", "--policy", "test_skill_mode:SkillPusher", "--action-mode", "skill",
                 "--reward-mode", "shaped", "--paper-car", "--episodes", "2", "--seed", "11", "--profile", "fast",
                 "--out", str(tmp_path)]) == 0
    records = json.loads((tmp_path / "episodes.json").read_text())["records"]
    assert len(records) == 2
    for r in records:  # the shaped return ranks every success above every failure
        assert r["return"] >= 1.0 if r["success"] else r["return"] <= -0.7 + 1e-9, r
