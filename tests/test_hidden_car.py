"""ReverseAlarm's hidden car: the R detent moves with its bumps, the alarm's relay delays it, and
both are drawn per episode out of the observation (issue 31, item 1)."""

import numpy as np
import pytest

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample
from acoustic_sim.world import names, scenes
from acoustic_sim.world.coupling import Coupling
from acoustic_sim.world.events import EventsConfig, SoundEvents
from acoustic_sim.world.lever_geometry import GearshiftGeometry
from apps.runner import run_episode
from policies.deaf import DeafLeverPolicy
from tasks.reverse_alarm import HIDDEN_VARIATION, ReverseAlarmEnv

DEG = np.pi / 180.0


def bump_angles_deg(model):
    """Lever angles (deg) at which each detent bump of the gearshift is under the roller."""
    lever = model.body(names.CAR + "gearshift_lever").id
    ids = [i for i in range(model.ngeom) if model.geom_bodyid[i] == lever and model.geom_contype[i] == 8]
    # A bump hangs 0.045 m below the pivot, turned by its frame's angle b about the body's y
    # axis: pos = 0.045 (-sin b, 0, -cos b); under the roller at lever angle b + 22.5 deg.
    return sorted(float(np.rad2deg(np.arctan2(-model.geom_pos[i][0], -model.geom_pos[i][2]))) + 22.5 for i in ids)


def test_the_assets_car_is_left_as_it_was():
    plain = scenes.build_scene("cabin").compile()
    default = scenes.build_scene("cabin", config=scenes.CabinConfig(reverse_deg=15.0)).compile()
    np.testing.assert_array_equal(plain.geom_quat, default.geom_quat)
    np.testing.assert_allclose(bump_angles_deg(plain), [-7.5, 7.5, 22.5, 37.5, 52.5], atol=1e-6)


@pytest.mark.parametrize("reverse_deg", [7.0, 11.0, 20.0, 23.0])
def test_reverse_detent_and_its_bumps_move(reverse_deg):
    model, data, _ = scenes.load_scene("cabin", config=scenes.CabinConfig(reverse_deg=reverse_deg))
    c = Coupling(model, data, None, rng=np.random.default_rng(0))
    np.testing.assert_allclose(np.rad2deg(c.view.gearshift_geometry.detents_rad), [0, reverse_deg, 30, 45], atol=1e-4)
    w = min(reverse_deg, 30 - reverse_deg) / 2
    np.testing.assert_allclose(bump_angles_deg(model), [-7.5, reverse_deg - w, reverse_deg + w, 37.5, 52.5], atol=1e-4)
    # A lever started in R rests in R: the roller holds it in the moved valley.
    model, data, _ = scenes.load_scene("cabin", config=scenes.CabinConfig(gear="R", reverse_deg=reverse_deg))
    c = Coupling(model, data, None, rng=np.random.default_rng(0))
    for _ in range(60):
        c.advance()
    assert c.view.gearshift_position() == "R"
    assert abs(np.rad2deg(c.view.gearshift_angle()) - reverse_deg) < 1.0


@pytest.mark.parametrize("bad", [6.9, 23.5, float("nan"), "15"])
def test_reverse_outside_the_gate_is_refused(bad):
    with pytest.raises(ConfigError, match="reverse_deg"):
        scenes.CabinConfig(reverse_deg=bad)


def gear_events(delay_s, trace):
    """Events of a synthetic gearshift trace (deg, one per 2 ms physics step) with the relay's delay."""
    gears = GearshiftGeometry(detents_rad=tuple(np.deg2rad([0.0, 15.0, 30.0, 45.0])))
    ev = SoundEvents(np.random.default_rng(0), emitters=["alarm", "gearshift"], gearshift=gears,
                     config=EventsConfig(alarm_delay_s=delay_s))
    ev.reset(sample=0, gear_angle=0.0)
    out = []
    for k in range(len(trace) // 8):
        pos = np.arange(8 * k + 1, 8 * k + 9) * (SAMPLE_RATE * 0.002)
        out += ev.process(frame_end_sample(k + 1), pos, gear_angles=np.asarray(trace[8 * k: 8 * k + 8]) * DEG)
    return out


def test_the_relay_delays_the_alarm_after_r_engages():
    trace = np.r_[np.linspace(0, 15, 250), np.full(1000, 15.0)]  # into R in 0.5 s, then held 2 s
    at_once = gear_events(0.0, trace)
    late = gear_events(0.7, trace)
    change = next(e.sample for e in at_once if e.kind == "gear_change")
    assert next(e.sample for e in at_once if e.kind == "alarm_start") == change
    assert next(e.sample for e in late if e.kind == "alarm_start") == change + round(0.7 * SAMPLE_RATE)


def test_leaving_r_before_the_relay_closes_silences_the_alarm():
    trace = np.r_[np.linspace(0, 15, 250), np.full(100, 15.0), np.linspace(15, 30, 250), np.full(600, 30.0)]
    out = gear_events(1.0, trace)  # 0.2 s in R, then on to N: the relay never closes
    assert [e.detail for e in out if e.kind == "gear_change"] == ["R", "N"]
    assert not any(e.kind.startswith("alarm") for e in out)


def test_hidden_parameters_are_drawn_per_episode_and_kept_out_of_the_observation():
    env = ReverseAlarmEnv(profile="fast", **HIDDEN_VARIATION)
    try:
        seen = []
        for seed in range(4):
            obs, info = env.reset(seed=seed)
            h = info["hidden"]
            assert HIDDEN_VARIATION["reverse_deg"][0] <= h["reverse_deg"] <= HIDDEN_VARIATION["reverse_deg"][1]
            assert HIDDEN_VARIATION["alarm_delay_s"][0] <= h["alarm_delay_s"] <= HIDDEN_VARIATION["alarm_delay_s"][1]
            assert np.rad2deg(env.view.gearshift_geometry.detents_rad[1]) == pytest.approx(h["reverse_deg"], abs=1e-4)
            assert not any("reverse" in k or "delay" in k or "hidden" in k for k in obs)
            seen.append(h)
        assert len({h["reverse_deg"] for h in seen}) == 4
        assert env.reset(seed=2)[1]["hidden"] == seen[2]  # same seed, same car
    finally:
        env.close()


class FixedAngle(DeafLeverPolicy):
    """The paper car's best deaf policy: the gearshift to 12 deg at 16 deg/s, let go at once."""

    side = "left"
    rate_deg_s = 16.0
    target_deg = 12.0


def test_a_fixed_angle_misses_a_car_with_another_reverse():
    env = ReverseAlarmEnv(profile="fast", reverse_deg=(20.0, 20.0), alarm_delay_s=(1.0, 1.0), success_window_s=1.0)
    try:
        deaf = run_episode(env, FixedAngle(env), 5)  # 12 deg: the paper car's R, not this one's
        assert deaf["outcome"] == "early" and deaf["target_onset_s"] is None
        # This car's R, less the taught motion's lead (the hand's pose for angle a moves the
        # lever to about a + 3 deg: the paper car's best deaf angle, 12, stands for its R at 15).
        lead = 15.0 - FixedAngle.target_deg
        held = run_episode(env, FixedAngle(env, target_deg=20.0 - lead, rate_deg_s=8.0, wait_s=1.3), 5)
        assert held["outcome"] == "success"
        change = next(e["time_s"] for e in held["events"] if e["kind"] == "gear_change")
        assert held["target_onset_s"] - change == pytest.approx(1.0, abs=1.5 / SAMPLE_RATE)
    finally:
        env.close()


@pytest.mark.parametrize("kwargs, match", [({"reverse_deg": (5.0, 15.0)}, "reverse_deg"),
                                           ({"reverse_deg": (18.0, 12.0)}, "reverse_deg"),
                                           ({"alarm_delay_s": (0.1, 6.0)}, "alarm_delay_s"),
                                           ({"alarm_delay_s": 0.5}, "alarm_delay_s")])
def test_bad_ranges_are_refused(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        ReverseAlarmEnv(profile="fast", **kwargs)
