"""The deaf and random baselines: they never read the percept, repeat with the seed, plug into
the runner, and the deaf search picks its best point."""

import numpy as np
import pytest

from acoustic_sim.errors import ConfigError
from apps import deaf_search, runner
from policies import POLICIES, make_policy, policy_class
from policies.deaf import POLICY_CLASSES as DEAF, SEARCH_PARAMETERS
from tasks.reverse_alarm import ReverseAlarmEnv

PERCEPT_KEYS = ("class_prob", "class_conf", "class_dir", "tracked_dir", "tracked_conf", "tracked_decided", "audio",
                "spectra")


class NoPercept(dict):
    """An observation whose percept entries cannot be read: a deaf policy must not try."""

    def __getitem__(self, key):
        if key in PERCEPT_KEYS:
            raise AssertionError(f"the deaf policy read the percept ({key!r})")
        return super().__getitem__(key)

    def get(self, key, default=None):
        return self[key] if key in self else default


@pytest.fixture(scope="module")
def envs():
    made = {task: runner.make_env(task, profile="fast") for task in runner.TASK_NAMES}
    yield made
    for env in made.values():
        env.close()


def actions(env, policy, seed, steps, wrap=lambda o: o):
    obs, info = env.reset(seed=seed)
    policy.reset(wrap(obs), info, seed)
    out = []
    for _ in range(steps):
        a = policy.act(wrap(obs), info)
        out.append(a)
        obs, _, terminated, truncated, info = env.step(a)
        if terminated or truncated:
            break
    return np.array(out)


@pytest.mark.parametrize("task", runner.TASK_NAMES)
def test_deaf_never_reads_the_percept(envs, task):
    env = envs[task]
    policy = make_policy("deaf", env)
    a = actions(env, policy, 100, 200, wrap=NoPercept)
    assert len(a) > 10 and np.all(np.isfinite(a))
    # Its actions do not depend on what is heard: the same with another episode's sounds
    # (ReverseAlarm: the same car without distractors; the hand feels the car's detents).
    if task == "reverse-alarm":
        quiet = runner.make_env(task, profile="fast", distractors=False)
        try:
            b = actions(quiet, make_policy("deaf", quiet), 100, len(a), wrap=NoPercept)
        finally:
            quiet.close()
    else:
        b = actions(env, make_policy("deaf", env), 101, len(a), wrap=NoPercept)
    if task != "call-response":  # the room's sweep steers by odometry, which the episode moves
        n = min(len(a), len(b))
        np.testing.assert_array_equal(a[:n], b[:n])


@pytest.mark.parametrize("task", runner.TASK_NAMES)
def test_deaf_parameters_are_constructor_arguments(envs, task):
    cls = DEAF[task]
    defaults = {k: getattr(cls, k) for k in SEARCH_PARAMETERS[task]}
    policy = make_policy("deaf", envs[task], **defaults)
    assert {k: getattr(policy, k) for k in defaults} == defaults
    with pytest.raises(ValueError):
        make_policy("deaf", envs[task], **{SEARCH_PARAMETERS[task][0]: -1.0})


def test_deaf_lever_lets_go_when_its_clock_says(envs):
    env = envs["parking-brake"]
    policy = make_policy("deaf", env, target_deg=16.0, rate_deg_s=8.0, wait_s=0.3)
    a = actions(env, policy, 100, 400)
    grasp = a[:, env.layout.index("grasp_right")]
    first_open = int(np.argmax(grasp < 0))
    assert grasp[first_open] < 0 and np.all(grasp[:first_open] > 0)
    # 0.2 s delay + 16 / 8 s travel + 0.3 s wait = 2.5 s = step 156.25 -> the 157th action.
    assert first_open == int(np.ceil(2.5 / 0.016 - 1e-9))


def test_deaf_gearshift_lets_go_a_wait_after_the_felt_detent():
    # A car with R at 18 deg and a 0.6 s relay: the hand feels R's valley a little after R
    # engages (0.44 s at 8 deg/s), waits, lets go: too soon, in the window, too late.
    env = ReverseAlarmEnv(profile="fast", reverse_deg=(18.0, 18.0), alarm_delay_s=(0.6, 0.6), distractors=False)
    try:
        for wait, outcome in ((0.0, "early"), (0.4, "success"), (1.0, "late")):
            policy = make_policy("deaf", env, rate_deg_s=8.0, wait_s=wait)
            record = runner.run_episode(env, policy, 100)
            assert record["outcome"] == outcome, (wait, record["outcome"])
            assert policy.felt_s is not None and policy.feel.felt == 1
            change = next(e["time_s"] for e in record["events"] if e["kind"] == "gear_change")
            lag = record["release_s"] - wait - change  # from R engaging to the feel
            assert 0.2 < lag < 0.6, lag
    finally:
        env.close()


@pytest.mark.parametrize("task", runner.TASK_NAMES)
def test_random_repeats_with_the_seed(envs, task):
    env = envs[task]
    a = actions(env, make_policy("random", env), 7, 5)
    b = actions(env, make_policy("random", env), 7, 5)
    c = actions(env, make_policy("random", env), 8, 5)
    n = min(len(a), len(b), len(c))
    np.testing.assert_array_equal(a[:n], b[:n])
    assert not np.array_equal(a[:1], c[:1])
    assert np.all(np.abs(a) <= 1.0)


def test_random_hold_keeps_the_hands_closed(envs):
    env = envs["parking-brake"]
    a = actions(env, make_policy("random-hold", env), 3, 60)
    grasp = [env.layout.index(n) for n in ("grasp_left", "grasp_right")]
    assert len(a) == 60 and np.all(a[:, grasp] == 1.0)
    others = np.delete(a, grasp, axis=1)
    assert others.std() > 0.3  # the joints are drawn uniformly on [-1, 1] (std 0.58)


def test_a_policy_class_by_module_and_name(envs, tmp_path):
    result = runner.run_episodes("reverse-alarm", "policies.deaf:DeafReverseAlarm", 1, 100, tmp_path, profile="fast",
                                 progress=False)
    deaf = runner.run_episode(envs["reverse-alarm"], make_policy("deaf", envs["reverse-alarm"]), 100)
    assert result["records"][0]["outcome"] == deaf["outcome"] and result["records"][0]["steps"] == deaf["steps"]
    assert policy_class("policies.random_policy:RandomPolicy", "call-response").__name__ == "RandomPolicy"


@pytest.mark.parametrize("name, match", [("nowhere.module:Policy", "cannot load"), ("policies.deaf:Nothing", "cannot load"),
                                         ("policies.deaf:SEARCH_PARAMETERS", "must be a class"),
                                         ("telepathic", "unknown policy")])
def test_bad_policy_names_are_refused(name, match):
    with pytest.raises(ConfigError, match=match):
        policy_class(name, "reverse-alarm")


def test_every_named_policy_has_every_task():
    for name in POLICIES:
        for task in runner.TASK_NAMES:
            assert callable(policy_class(name, task))


def test_deaf_search_refuses_held_out_seeds():
    with pytest.raises(ConfigError, match="design seeds"):
        deaf_search.search("reverse-alarm", episodes=2, seed=3000, progress=False)
    with pytest.raises(ConfigError, match="unknown task"):
        deaf_search.grid_points("juggling")


def test_deaf_search_picks_the_most_successful_point(monkeypatch):
    # One car (R at 18 deg, a 0.6 s relay) and two waits after the felt detent (which comes
    # 0.44 s after R engages): none lets go before the alarm, 0.4 s within its window.
    make_env = runner.make_env
    monkeypatch.setattr(runner, "make_env", lambda task, **kw: make_env(task, reverse_deg=(18.0, 18.0),
                                                                         alarm_delay_s=(0.6, 0.6), **kw))
    monkeypatch.setitem(deaf_search.GRIDS, "reverse-alarm", {"rate_deg_s": (8.0,), "wait_s": (0.0, 0.4)})
    result = deaf_search.search("reverse-alarm", episodes=2, seed=100, progress=False)
    assert [p["params"]["wait_s"] for p in result["points"]] == [0.0, 0.4]
    assert result["points"][0]["success_rate"] == 0.0 and result["points"][0]["outcomes"] == {"early": 2}
    assert result["best"]["params"]["wait_s"] == 0.4 and result["best"]["success_rate"] == 1.0
    assert "deaf search, reverse-alarm" in deaf_search.ranking(result)
