"""``train policy`` and ``learned:PATH``: a tiny PPO run end to end (two envs in subprocesses),
saved, reloaded and acting as it did; a policy refused in an env it was not trained for.

No success rate is asserted: a few hundred steps teach nothing; ``eval tasks`` measures that.
"""

import csv
import json

import numpy as np
import pytest

from acoustic_sim.errors import ConfigError
from apps import learn, runner
from policies import make_policy
from policies.learned import LearnedPolicy

TINY = {"n_steps": 128, "batch_size": 64, "n_epochs": 2}


@pytest.fixture(scope="module")
def trained(tmp_path_factory, model_cache):
    out = tmp_path_factory.mktemp("learned") / "cr"
    meta, model = learn.train_policy("call-response", out=out, steps=512, envs=2, seed=3, progress=False,
                                     ppo_args=TINY, return_model=True)
    return out, meta, model


def test_training_writes_the_policy_its_metadata_metrics_and_curve(trained):
    out, meta, _ = trained
    for name in ("policy.zip", "policy.json", "progress.csv", "episodes.csv", "learning_curve.png"):
        assert (out / name).is_file(), name
    saved = json.loads((out / "policy.json").read_text())
    assert saved == json.loads(json.dumps(meta))
    assert saved["task"] == "call-response" and saved["action_mode"] == "skill" and saved["reward_mode"] == "shaped"
    assert saved["steps"] >= 512 and saved["envs"] == 2 and saved["seed"] == 3
    assert set(saved["auditory_checkpoints"]) == {"ssdenet", "melcnn"}
    assert all(len(c["sha256"]) == 16 for c in saved["auditory_checkpoints"].values())
    assert saved["observation"]["class_dir"] == [18]
    rows = list(csv.DictReader(open(out / "progress.csv")))
    assert len(rows) == 2 and "rollout/success_rate" in rows[0] and "train/loss" in rows[-1]
    episodes = list(csv.DictReader(open(out / "episodes.csv")))
    assert len(episodes) == saved["episodes"] > 0
    assert all(int(e["success"]) in (0, 1) and int(e["length"]) > 0 for e in episodes)


def test_the_reloaded_policy_acts_as_the_trained_one(trained):
    out, _, model = trained
    env = runner.make_env("call-response", profile="fast", action_mode="skill", reward_mode="shaped")
    try:
        policy = make_policy(f"learned:{out}", env)
        assert isinstance(policy, LearnedPolicy)
        obs, info = env.reset(seed=3000)
        policy.reset(obs, info, 3000)
        for _ in range(40):
            a = policy.act(obs, info)
            b, _ = model.predict(obs, deterministic=True)
            np.testing.assert_array_equal(a, np.asarray(b, np.float32))
            obs, _, terminated, truncated, info = env.step(a)
            if terminated or truncated:
                break
    finally:
        env.close()


def test_run_takes_the_policy_modes_and_repeats(trained, tmp_path):
    out, _, _ = trained
    a = runner.run_episodes("call-response", f"learned:{out}", 2, 3000, tmp_path / "a", profile="fast", progress=False)
    b = runner.run_episodes("call-response", f"learned:{out}", 2, 3000, tmp_path / "b", profile="fast", progress=False)
    strip = [{k: v for k, v in r.items() if k != "wall_s"} for r in a["records"]]
    assert strip == [{k: v for k, v in r.items() if k != "wall_s"} for r in b["records"]]


def test_a_mismatched_policy_is_refused(trained, tmp_path):
    out, _, _ = trained
    with pytest.raises(ConfigError, match="trained for call-response, not reverse-alarm"):
        runner.run_episodes("reverse-alarm", f"learned:{out}", 1, 0, tmp_path / "r", profile="fast", progress=False)
    with pytest.raises(ConfigError, match="action_mode='skill', not 'joints'"):
        runner.run_episodes("call-response", f"learned:{out}", 1, 0, tmp_path / "r", profile="fast", progress=False,
                            env_kwargs={"action_mode": "joints"})
    # A policy whose observation holds a key this env lacks (or shapes it otherwise) is refused.
    other = tmp_path / "other"
    other.mkdir()
    (other / "policy.zip").write_bytes((out / "policy.zip").read_bytes())
    meta = json.loads((out / "policy.json").read_text())
    meta["observation"]["audio"] = [2, 706]
    (other / "policy.json").write_text(json.dumps(meta))
    env = runner.make_env("call-response", profile="fast", action_mode="skill")
    try:
        with pytest.raises(ConfigError, match="trained on observations"):
            LearnedPolicy(env, other)
    finally:
        env.close()
    joints = runner.make_env("call-response", profile="fast")
    try:
        with pytest.raises(ConfigError, match="skill action mode"):
            LearnedPolicy(joints, out)
    finally:
        joints.close()
    with pytest.raises(ConfigError, match="does not exist"):
        make_policy(f"learned:{tmp_path}/none", joints)
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "policy.zip").write_bytes(b"")
    (tmp_path / "broken" / "policy.json").write_text("{not json")
    with pytest.raises(ConfigError, match="cannot read"):
        make_policy(f"learned:{tmp_path}/broken", joints)


def test_keys_added_to_the_observation_since_training_are_left_out(trained):
    """An env that gives more than the network read (the audio here) runs the policy on the
    training's keys: the same actions as in an env without them."""
    out, _, _ = trained
    plain = runner.make_env("call-response", profile="fast", action_mode="skill")
    more = runner.make_env("call-response", profile="fast", action_mode="skill", audio_obs=True)
    try:
        a, b = LearnedPolicy(plain, out), LearnedPolicy(more, out)
        obs_a, info_a = plain.reset(seed=5)
        obs_b, info_b = more.reset(seed=5)
        assert "audio" in obs_b and "audio" not in a.keys
        np.testing.assert_array_equal(a.act(obs_a, info_a), b.act(obs_b, info_b))
    finally:
        plain.close()
        more.close()


def test_bad_training_arguments_are_config_errors(tmp_path):
    for kwargs, match in (({"steps": 0}, "steps"), ({"envs": 0}, "envs"), ({"seed": -1}, "seed"),
                          ({"algo": "dqn"}, "algorithm")):
        with pytest.raises(ConfigError, match=match):
            learn.train_policy("call-response", out=tmp_path / "x", **kwargs)
    with pytest.raises(ConfigError, match="unknown task"):
        learn.train_policy("juggling", out=tmp_path / "x")
    assert not (tmp_path / "x").exists()


def test_eval_tasks_runs_a_learned_policy_on_its_own_task(trained, tmp_path):
    from apps.eval_tasks import run_tasks

    out, _, _ = trained
    data = run_tasks(out=tmp_path / "tasks", quick=True, episodes=1, progress=False, policies=[f"learned:{out}"])
    assert [(r["task"], r["policy"]) for r in data["rows"]] == [("call-response", "learned")]
    assert (tmp_path / "tasks" / "call-response" / "learned" / "episodes.json").is_file()
