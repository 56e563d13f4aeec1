"""Headless task regression tests: the policies over seeded episodes (``fast`` profile).

``oracle`` (ground truth) must meet every target: that checks the tasks, their outcomes and
their timing. ``scripted`` (the paper's behaviours, from the percepts) and ``blind`` (classes
without directions) depend on the auditory pipeline: a probe first checks that the ``fast``
models detect the task sounds at all (a failure if not). The scripted policies are held to
the issue's targets (success at least 0.9, no false release, the median reactions) over
these 20 episodes. Until 2026-12-04 (session 21) the cabin targets were expected failures
with a floor below: the 16-bin fast SSDENet bank gave ReverseAlarm 18, 15 and 14 of 20 with
one false release each for training seeds 0, 1 and 2. Since the line-of-sight law for
outside sounds, the lateral rule of :class:`policies.scripted_cabin.ScriptedReverseAlarm` and the
jittered 32-bin fast bank (:data:`acoustic_sim.auditory.ssdenet.recipes.FAST`; measurements in
docs/notes/ssdenet_recipes.md), the three training seeds give ReverseAlarm 19, 20 and 18
and ParkingBrake 19, 18 and 19 of 20, none with a false release. CI trains its own models
on another CPU, which is another draw: a fast bank lets go falsely in about 0-4 % of cabin
episodes, so a failure here is worth a look at the episode (``acoustic-sim run TASK
--policy scripted --seed S --episodes 1 --profile fast``) before the models are blamed.
These targets are the paper's car (``--paper-car``); in the hidden car (the default, R and the
alarm's latency drawn per episode) the test asks that hearing decide: the scripted policy well
above the deaf one (0.75 against 0.45 on these seeds; docs/notes/alarm_policy.md). So does
CallResponse, with three people in the room (docs/notes/call_response.md).
"""

import json

import numpy as np
import pytest

from acoustic_sim.errors import ConfigError
from apps import runner
from policies import POLICIES, make_policy
from tasks.reverse_alarm import PAPER_CAR

EPISODES = 20
BLIND_EPISODES = 12  # enough to show that the distractors bite
@pytest.fixture(scope="module")
def envs():
    # ReverseAlarm in the paper's car (R at 15 deg, the alarm at once): the regression of the
    # pipeline and the scripted rule; the hidden car (the default) is tested below.
    made = {t: runner.make_env(t, profile="fast", **(PAPER_CAR if t == "reverse-alarm" else {}))
            for t in runner.TASK_NAMES}
    made["hidden-car"] = runner.make_env("reverse-alarm", profile="fast")
    yield made
    for env in made.values():
        env.close()


@pytest.fixture(scope="module")
def hearing(envs):
    """Whether the fast MelCNN detects the tasks' target sounds at all (probe, ~1 s)."""
    from acoustic_sim.acoustics import sounds
    from acoustic_sim.acoustics.microphone import Microphone
    from acoustic_sim.acoustics.renderer import BinauralRenderer
    from acoustic_sim.acoustics.room import room_preset
    from acoustic_sim.frames import rotation_zyx, sph_to_vec
    from tasks.base import CLASSES, make_pipeline

    pipe = make_pipeline("fast")
    hits = {}
    for label in ("reverse_alarm", "ratchet", "human_voice"):
        rng = np.random.default_rng(5)
        space = room_preset("anechoic")
        r = BinauralRenderer(pipe.hrtf, space, rng=rng)
        r.set_head_pose(np.zeros(3), rotation_zyx(0.0))
        r.add_source("s", sounds.generate(label, rng, seconds=1.0), 1.5 * sph_to_vec(30.0, 0.0), level_db=75.0, start=0)
        percepts = pipe.process(Microphone(rng=rng)(r.render(1.0)))
        hits[label] = float(np.mean([p.probabilities[CLASSES.index(label)] >= 0.5 for p in percepts[25:]]))
    return hits


def need(hearing, *labels):
    bad = {k: v for k, v in hearing.items() if k in labels and v < 0.3}
    if bad:
        # A failure, not an xfail: a fast MelCNN that stops detecting a class is a regression
        # (the 8-filter recipe once trained to one that never detected a voice, and the
        # xfail hid it; the 16-filter one gives macro F1 0.60-0.73 over three seeds).
        pytest.fail(f"the fast MelCNN does not detect {sorted(bad)} (fraction of frames detected: {bad})")


RESULTS: dict = {}


def episodes(envs, task, policy, n=EPISODES, seed=100):
    key = (task, policy, n, seed)
    if key not in RESULTS:
        env = envs[task]
        pol = make_policy(policy, env)
        records = [runner.run_episode(env, pol, seed + i, episode=i) for i in range(n)]
        RESULTS[key] = (runner.summarize(records), records)
        s = RESULTS[key][0]
        print(f"\n{task} {policy}: success {s['success_rate']}, false releases {s['false_release_rate']}, "
              f"median reaction {s['median_reaction_s']} s, outcomes {s['outcomes']}")
    return RESULTS[key]


# -- the oracle: the tasks themselves ------------------------------------------------------------------


@pytest.mark.parametrize("task", runner.TASK_NAMES)
def test_oracle_meets_every_target(envs, task):
    summary, records = episodes(envs, task, "oracle", n=4)
    assert summary["success_rate"] == 1.0, summary["outcomes"]
    assert summary["false_release_rate"] == 0.0
    limit = 1.1 if task == "call-response" else 0.05  # a step after the sound; the room: turning and a look
    assert all(r["reaction_s"] is not None and r["reaction_s"] <= limit for r in records), [r["reaction_s"] for r in records]


# -- blind and scripted: what hearing the direction is worth ----------------------------------------------


@pytest.mark.parametrize("task", ["reverse-alarm", "parking-brake"])
def test_blind_lets_go_on_distractors(envs, hearing, task):
    need(hearing, "reverse_alarm" if task == "reverse-alarm" else "ratchet", "human_voice")
    summary, _ = episodes(envs, task, "blind", n=BLIND_EPISODES)
    assert summary["false_release_rate"] >= 0.25, summary


@pytest.mark.parametrize("task", ["reverse-alarm", "parking-brake"])
def test_scripted_lets_go_falsely_less_often_than_blind(envs, hearing, task):
    need(hearing, "reverse_alarm" if task == "reverse-alarm" else "ratchet", "human_voice")
    scripted, _ = episodes(envs, task, "scripted")
    blind, _ = episodes(envs, task, "blind", n=BLIND_EPISODES)
    assert scripted["false_release_rate"] < blind["false_release_rate"], (scripted, blind)


@pytest.mark.parametrize("task, label, reaction_s", [("reverse-alarm", "reverse_alarm", 0.5),
                                                      ("parking-brake", "ratchet", 0.3)])
def test_scripted_cabin_targets(envs, hearing, task, label, reaction_s):
    """Success at least 0.9, no false release, and the issue's median reaction (0.5 s for the
    alarm, 0.3 s for the ratchet; the paper's robot took 2.3 s and 0.2 s)."""
    need(hearing, label)
    summary, records = episodes(envs, task, "scripted")
    failed = [(r["seed"], r["outcome"]) for r in records if not r["success"]]  # the episodes to look at
    assert summary["success_rate"] >= 0.9 and summary["false_release_rate"] == 0.0, (summary, failed)
    assert summary["median_reaction_s"] <= reaction_s, summary


def test_hearing_decides_the_hidden_car(envs, hearing):
    """In the default car (R and the relay's latency hidden) the oracle succeeds, the deaf
    policy, which feels R's detent but cannot hear the alarm, is held near its bound (a 0.4 s
    window over 1.4 s of latencies: 0.29), and the scripted policy, which listens, does far
    better (0.75 against 0.45 here; the margin 0.15 leaves room for another training draw of
    the fast models). The deaf rate does not depend on the models (it never reads the percept)."""
    need(hearing, "reverse_alarm")
    oracle, _ = episodes(envs, "hidden-car", "oracle", n=4)
    deaf, _ = episodes(envs, "hidden-car", "deaf")
    scripted, records = episodes(envs, "hidden-car", "scripted")
    assert oracle["success_rate"] == 1.0, oracle["outcomes"]
    assert deaf["success_rate"] <= 0.5, deaf
    failed = [(r["seed"], r["outcome"], r["reaction_s"]) for r in records if not r["success"]]
    assert scripted["success_rate"] >= deaf["success_rate"] + 0.15 and scripted["false_release_rate"] <= 0.05, \
        (scripted, deaf, failed)


def test_call_response_hearing_decides(envs, hearing):
    """Three people, one calls: the deaf scan (the search's winner on these very seeds, so
    its best case) looks at the caller in 6 of 20, the scripted policy in 14 of 20 with these
    fast models (their front-back cues are near chance: docs/notes/call_response.md); 0.2
    apart leaves room for another training draw. The deaf rate does not depend on the models."""
    need(hearing, "human_voice")
    deaf, _ = episodes(envs, "call-response", "deaf")
    scripted, records = episodes(envs, "call-response", "scripted")
    assert deaf["success_rate"] <= 0.35, deaf
    assert scripted["success_rate"] >= deaf["success_rate"] + 0.2, (scripted, deaf)
    window = envs["call-response"].response_window_s
    assert all(r["reaction_s"] <= window + 0.02 for r in records if r["success"])


# -- the runner and the policies' API -----------------------------------------------------------------------


def test_run_episodes_writes_episodes_json_and_a_table(tmp_path, capsys):
    result = runner.run_episodes("parking-brake", "oracle", 2, 3, tmp_path / "run", profile="fast", progress=True)
    data = json.loads((tmp_path / "run" / "episodes.json").read_text())
    assert data["summary"] == result["summary"] and len(data["records"]) == 2
    assert [r["seed"] for r in data["records"]] == [3, 4]
    for key in ("success_rate", "median_reaction_s", "false_release_rate"):
        assert key in data["summary"]
    s = data["summary"]
    assert s["success_rate_ci95"] == runner.rate_interval(round(2 * s["success_rate"]), 2)
    assert s["false_release_rate_ci95"] == runner.rate_interval(round(2 * s["false_release_rate"]), 2)
    out = capsys.readouterr().out
    assert "success_rate" in out and "false_release_rate" in out and "(95 % " in out


def test_rate_interval_is_wilson_s():
    # Wilson's score interval, closed form: (p + z^2/2n -+ z sqrt(p(1-p)/n + z^2/4n^2)) / (1 + z^2/n).
    z = 1.959964
    for k, n in ((28, 30), (18, 20), (0, 30), (20, 20), (1, 2)):
        p = k / n
        centre, half = p + z * z / (2 * n), z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
        expect = [(centre - half) / (1 + z * z / n), (centre + half) / (1 + z * z / n)]
        assert runner.rate_interval(k, n) == pytest.approx(expect, abs=1e-4)
    assert runner.rate_interval(28, 30) == pytest.approx([0.7868, 0.9815], abs=1e-4)
    # No false release in 30 episodes still allows a rate of 11 %.
    assert runner.rate_interval(0, 30)[0] == 0.0 and runner.rate_interval(0, 30)[1] > 0.1
    assert runner.rate_interval(0, 0) is None
    with pytest.raises(ConfigError, match="within 0..5"):
        runner.rate_interval(6, 5)


def test_run_command_line(tmp_path):
    import argparse

    parser = argparse.ArgumentParser(prog="acoustic-sim")
    runner.add_parsers(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["run", "parking-brake", "--policy", "oracle", "--episodes", "1", "--seed", "2",
                              "--out", str(tmp_path), "--profile", "fast"])
    assert args.func(args) == 0 and (tmp_path / "episodes.json").is_file()
    with pytest.raises(SystemExit):
        parser.parse_args(["run", "juggling", "--out", str(tmp_path)])


def test_step_callback_sees_every_step(envs):
    seen = []
    env = envs["parking-brake"]
    record = runner.run_episode(env, make_policy("oracle", env), 1, step_callback=lambda e, ep, k, *rest: seen.append(k))
    assert seen == list(range(record["steps"] + 1))


def test_policy_and_runner_errors(envs):
    with pytest.raises(ConfigError, match="unknown policy"):
        make_policy("telepathic", envs["reverse-alarm"])
    with pytest.raises(ConfigError, match="not a hearing task"):
        import gymnasium as gym

        make_policy("scripted", gym.make("CartPole-v1"))
    with pytest.raises(ConfigError, match="unknown task"):
        runner.make_env("juggling")
    with pytest.raises(ConfigError, match="episodes"):
        runner.run_episodes("reverse-alarm", "oracle", 0, 0, "unused", profile="fast", progress=False)
    assert set(POLICIES) == set(runner.POLICY_NAMES)


def test_reverse_alarm_listening_pose_and_lateral_rule(envs):
    """The scripted ReverseAlarm policy turns the head 22 deg right and accepts a lateral
    angle of 5-36 deg to the left of the turned head (the dashboard speaker, 22 deg, and its
    front-back mirror image behind, which the ears cannot tell apart), not above 20 deg,
    nothing else."""
    import math

    from acoustic_sim.frames import sph_to_vec
    from policies.scripted_cabin import ScriptedReverseAlarm

    env = envs["reverse-alarm"]
    pol = ScriptedReverseAlarm(env)
    obs, info = env.reset(seed=5)
    pol.reset(obs, info)
    for _ in range(40):  # the head settles in the listening pose (the lever still waits or creeps)
        obs, *_, info = env.step(pol.act(obs, info))
    assert pol.head_yaw_deg == -22.0 and pol.lateral_range_deg == (5.0, 36.0)
    assert math.degrees(float(obs["joint_pos"][0])) == pytest.approx(pol.head_yaw_deg, abs=3.0)
    pose = {"joint_pos": np.radians([pol.head_yaw_deg, 0.0])}

    def accepts(head_az_deg, el_deg=0.0):
        return pol.accept(sph_to_vec(head_az_deg, el_deg), pose)

    assert accepts(22.0) and accepts(22.0 + 12.0) and accepts(22.0 - 15.0)  # in front of the car: 0, +12, -15 deg
    assert accepts(158.0) and accepts(180.0 - 34.0)  # the mirror images behind: the same lateral angles
    assert not accepts(-22.0) and not accepts(0.0) and not accepts(60.0) and not accepts(90.0) and not accepts(-158.0)
    # The elevations: the dashboard's beeps, placed 30-50 deg down, count; 30 deg or more up
    # (above the head, not the dashboard) does not, nor its mirror image.
    assert pol.elevation_deg == (-90.0, 20.0)
    assert accepts(25.0, -30.0) and accepts(155.0, -30.0) and accepts(30.0, -50.0) and accepts(22.0, 15.0)
    assert not accepts(22.0, 30.0) and not accepts(158.0, 40.0) and not accepts(40.0, 60.0)


def test_parking_brake_hears_the_right_by_lateral_angle(envs):
    """"From the right" is a lateral angle of at least 20 deg to the right, wherever on the
    cone of confusion the estimate falls: the ratchet's pawl (-108 deg, -63 deg: lateral 26
    deg), its estimates and their mirror images count, the radio in front (-17 deg) and its
    mirror image behind (-164 deg, the traced early release) do not, nor anything on the left."""
    from acoustic_sim.frames import lateral_deg, sph_to_vec
    from policies.scripted_cabin import ScriptedParkingBrake

    pol = ScriptedParkingBrake(envs["parking-brake"])
    assert lateral_deg(sph_to_vec(-90.0, 0.0)) == pytest.approx(-90.0)
    assert lateral_deg(sph_to_vec(-150.0, 0.0)) == pytest.approx(-30.0)
    assert pol.lateral_deg == 20.0
    assert lateral_deg(sph_to_vec(30.0, 60.0)) == pytest.approx(14.48, abs=0.01)  # asin(cos 60 sin 30)
    for az, el in ((-108.0, -63.0), (-72.0, -63.0), (-110.0, 0.0), (-70.0, -30.0), (-62.1, -30.0), (-111.7, 30.0)):
        assert pol.accept(sph_to_vec(az, el), None), (az, el)
    for az, el in ((-17.0, 0.0), (-163.6, 10.0), (-150.0, 80.0), (63.9, -20.0), (48.5, -40.0), (0.0, -90.0)):
        assert not pol.accept(sph_to_vec(az, el), None), (az, el)


def test_lever_waits_for_quiet_and_credits_only_its_own_clicks(envs):
    """The cabin policies' "waiting for quiet" (:class:`policies.cabin_policy.CabinLeverPolicy`):
    the lever stops while another class masks and until ``masker_quiet_s`` of quiet, and
    for ``settle_s`` after its own class was last heard; a ratchet click from the right
    decides only within ``credit_s`` of the lever's last motion (fake observations: the
    policy reads only the percept)."""
    from policies.scripted_cabin import ScriptedParkingBrake
    from tasks.base import CLASSES, CONTROL_DT

    env = envs["parking-brake"]
    pol = ScriptedParkingBrake(env)
    obs, info = env.reset(seed=3)
    pol.reset(obs, info)
    right = np.array([0.0, -1.0, 0.0])  # lateral -90 deg: accepted
    left = -right

    def frame(**probs):
        o = {k: np.array(v, copy=True) for k, v in obs.items()}
        o["class_prob"][:] = 0.0
        o["class_conf"][:] = 0.0
        o["class_dir"][:] = 0.0
        for label, (p, d) in probs.items():
            i = CLASSES.index(label)
            o["class_prob"][i] = p
            if d is not None:
                o["class_dir"][3 * i : 3 * i + 3], o["class_conf"][i] = d, 1.0
        return o

    def moved(o):
        before = pol.motion_s
        pol.act(o, None)
        return pol.motion_s > before

    assert moved(frame())  # quiet: the lever moves
    assert not moved(frame(key_turning=(0.9, None)))  # a masker: it waits
    masker_frames = round(pol.masker_quiet_s / CONTROL_DT)
    assert [moved(frame()) for _ in range(masker_frames + 1)] == [False] * (masker_frames - 1) + [True, True]
    # The relay (ratchet class, from the left): no release, and the lever waits settle_s after it.
    for _ in range(10):
        assert not moved(frame(ratchet=(0.95, left)))
    settle = round(pol.settle_s / CONTROL_DT)
    waits = [moved(frame()) for _ in range(settle + 1)]
    assert waits == [False] * (settle - 1) + [True, True] and not pol.released
    # A click from the right right after the lever moved: let go (two votes).
    pol.act(frame(ratchet=(0.9, right)), None)
    pol.act(frame(ratchet=(0.9, right)), None)
    assert pol.released

    # The same click after the lever has stood still longer than credit_s: not the brake's.
    pol.reset(obs, info)
    for _ in range(3):
        pol.act(frame(), None)
    for _ in range(round(pol.credit_s / CONTROL_DT) + 2):
        pol.act(frame(human_voice=(0.9, None)), None)  # the radio: the lever waits
    for _ in range(pol.window):
        pol.act(frame(ratchet=(0.9, right), human_voice=(0.9, None)), None)
    assert not pol.released
