"""CallResponse in a crowd: who stands where, what counts as a look, the response window.

The rules under test (tasks/call_response.py): two or three people out of view and 60 deg
apart; the first person looked at after the call starts (in view, the gaze still for
``look_s``) decides; a gaze moving faster than STILL_DEG_S does not look; the window ends the
episode ``too_late``.
"""

import math

import mujoco
import numpy as np
import pytest

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names, scenes
from tasks.base import CONTROL_DT
from tasks.call_response import APART_DEG, LOOK_S, OUT_OF_VIEW_DEG, PAPER_ROOM, RESPONSE_WINDOW_S, CallResponseEnv


@pytest.fixture(scope="module")
def env():
    e = CallResponseEnv(profile="fast", distractors=False, people=(2, 3))
    yield e
    e.close()


def _bearing(env, body: str) -> float:
    """Bearing (deg, + left) of a body from the wheelchair's heading."""
    pos, rot = env.view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)
    p = env.view.body_pose(body)[0]
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    return math.degrees((math.atan2(p[1] - pos[1], p[0] - pos[0]) - yaw + math.pi) % (2 * math.pi) - math.pi)


def test_two_or_three_people_out_of_view_and_apart(env):
    counts = set()
    for seed in range(12):
        _obs, info = env.reset(seed=seed)
        n = info["people"]
        counts.add(n)
        heads = [names.PERSON_HEAD_BODY, *names.BYSTANDER_HEAD_BODIES[: n - 1]]
        bearings = [_bearing(env, h) for h in heads]
        assert all(abs(b) >= OUT_OF_VIEW_DEG - 3.0 for b in bearings), bearings  # heads vs feet: 3 deg
        for i in range(n):
            for j in range(i):
                assert abs((bearings[i] - bearings[j] + 180.0) % 360.0 - 180.0) >= APART_DEG - 3.0, bearings
        assert not any(env.person_in_view(h)[0] for h in heads)
        np.testing.assert_allclose(sorted(info["bystander_bearings_deg"]), sorted(bearings[1:]), atol=3.0)
    assert counts == {2, 3}


def test_three_people_by_default():
    e = CallResponseEnv(profile="fast", distractors=False)
    try:
        assert all(e.reset(seed=s)[1]["people"] == 3 for s in range(3))
    finally:
        e.close()


def test_the_paper_room_has_one_person_and_no_window():
    e = CallResponseEnv(profile="fast", distractors=False, **PAPER_ROOM)
    try:
        _obs, info = e.reset(seed=0)
        assert info["people"] == 1 and e.response_window_s is None and e.look_s == 0.0
    finally:
        e.close()


def _stand_in_front(env, body: str) -> None:
    """Move a person (root body) 1.2 m in front of the right eye, feet on the floor (inside
    the room: the seeds used put the wheelchair 1.5 m or more from the walls)."""
    cam = env.data.cam(names.EYE_CAMERAS[1])
    spot = cam.xpos + 1.2 * (-cam.xmat.reshape(3, 3)[:, 2])
    scenes.place_mocap(env.model, env.data, body, [spot[0], spot[1], 0.0], 0.0)
    mujoco.mj_forward(env.model, env.data)


def _run(env, action_at, limit_s: float = 5.0):
    """Step with ``action_at(step)`` until the episode ends; the last info and the steps."""
    k = 0
    while True:
        _obs, reward, terminated, truncated, info = env.step(action_at(k))
        k += 1
        if terminated or truncated or k * CONTROL_DT > limit_s:
            return reward, info, k


def _until_call(env) -> dict:
    """Step with the zero action until the first call has started; its info."""
    while True:
        _obs, _r, terminated, truncated, info = env.step(env.layout.action({}))
        assert not (terminated or truncated)
        if info["target_onset_s"] is not None:
            return info


def test_a_still_look_at_the_caller_after_the_call_succeeds(env):
    env.reset(seed=3)
    _until_call(env)
    _stand_in_front(env, names.PERSON_ROOT_BODY)
    start = env.time_s
    reward, info, _ = _run(env, lambda k: env.layout.action({}))
    assert info["outcome"] == "success" and reward == 1.0 and info["looked_at"] == "caller"
    assert env.time_s - start == pytest.approx(LOOK_S, abs=2 * CONTROL_DT)


def test_a_person_in_view_when_the_call_starts_counts_only_once_turned_to(env):
    """Parked on someone before the call, the gaze has not turned to the caller: no success
    while it stays; after looking away and back, the look counts."""
    env.reset(seed=3)
    _stand_in_front(env, names.PERSON_ROOT_BODY)
    away = env.layout.action({"neck_yaw": math.radians(80.0)})
    reward, info, steps = _run(env, lambda k: env.layout.action({}), limit_s=1.0)
    assert info["outcome"] == "running" and steps * CONTROL_DT > 1.0 - CONTROL_DT
    reward, info, _ = _run(env, lambda k: away if k < 20 else env.layout.action({}))
    assert info["outcome"] == "success", info["outcome"]


def test_looking_at_another_person_first_is_wrong_person(env):
    for seed in range(20):
        _obs, info = env.reset(seed=seed)
        if info["people"] == 3:
            break
    _until_call(env)
    _stand_in_front(env, names.BYSTANDERS[1] + "body")
    reward, info, _ = _run(env, lambda k: env.layout.action({}))
    assert info["outcome"] == "wrong_person" and reward == 0.0 and info["looked_at"] == "bystander2"
    assert not info["success"]


def test_a_moving_gaze_does_not_look(env):
    """The caller in view the whole time, but the neck swings 15 deg each way every 3 steps (the
    gaze turns at 100-290 deg/s): no look until the gaze holds still."""
    env.reset(seed=3)
    _until_call(env)
    _stand_in_front(env, names.PERSON_ROOT_BODY)
    start = env.time_s
    swings = 60
    swing = [env.layout.action({"neck_yaw": math.radians(15.0 * (1 if k % 2 else -1))}) for k in range(2)]
    reward, info, steps = _run(env, lambda k: swing[(k // 3) % 2] if k < swings else env.layout.action({}))
    assert info["outcome"] == "success" and steps > swings, (info["outcome"], steps)
    assert env.time_s - start >= swings * CONTROL_DT + LOOK_S - 2 * CONTROL_DT


def test_nobody_looked_at_is_too_late_when_the_window_ends(env):
    _obs, info = env.reset(seed=5)
    reward, info, _ = _run(env, lambda k: env.layout.action({}))
    assert info["outcome"] == "too_late" and reward == 0.0 and info["looked_at"] is None
    assert env.time_s - info["target_onset_s"] == pytest.approx(RESPONSE_WINDOW_S, abs=2 * CONTROL_DT)


@pytest.mark.parametrize("kwargs, match", [
    ({"people": (0, 2)}, "people"), ({"people": (3, 2)}, "people"), ({"people": (1, 4)}, "people"),
    ({"people": (1.5, 2)}, "people"), ({"response_window_s": 0.0}, "response_window_s"),
    ({"response_window_s": float("nan")}, "response_window_s"), ({"look_s": -0.1}, "look_s"),
])
def test_bad_crowd_arguments_are_config_errors(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        CallResponseEnv(profile="fast", **kwargs)


def test_bystanders_are_scene_config():
    spec = scenes.build_scene("room", config=scenes.RoomConfig(bystanders=((1.0, 1.0, 0.0), (4.0, 4.0, 90.0))))
    model = spec.compile()
    assert all(model.body(h).id > 0 for h in names.BYSTANDER_HEAD_BODIES)
    with pytest.raises(ConfigError, match="bystanders"):
        scenes.RoomConfig(bystanders=((1.0, 1.0),))
    with pytest.raises(ConfigError, match="bystanders"):
        scenes.RoomConfig(bystanders=((1.0, 1.0, 0.0),) * 3)
