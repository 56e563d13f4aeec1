"""Sound events from physics: trackers on angle traces, the event source, the real cabin, ego-noise."""

import numpy as np
import pytest
from scipy import signal

from acoustic_sim.acoustics.sounds.cutting import alarm_loop, gearshift_throws, onsets, ratchet_clicks
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample
from acoustic_sim.world import names, scenes
from acoustic_sim.world.coupling import Coupling
from acoustic_sim.world.egonoise import EgoNoiseConfig, MotorEgoNoise
from acoustic_sim.world.events import EMITTERS, EventsConfig, GearshiftTracker, RatchetTracker, SoundEvents
from acoustic_sim.world.lever_geometry import GearshiftGeometry, RatchetGeometry

DEG = np.pi / 180.0
GEARS = GearshiftGeometry(detents_rad=tuple(np.deg2rad([0.0, 15.0, 30.0, 45.0])))
TEETH = RatchetGeometry(teeth_rad=tuple(np.deg2rad(8.0 + 7.0 * np.arange(7))))


def ramp(points, dt=0.002):
    """A piecewise-linear trace sampled every ``dt`` s after t=0: points are (t, value)."""
    t, v = np.asarray(points, dtype=float).T
    ts = np.arange(1, round(t[-1] / dt) + 1) * dt
    return np.interp(ts, t, v)


# -- trackers ----------------------------------------------------------------------------------------


def test_gearshift_tracker_p_r_n():
    g = GearshiftTracker(GEARS, 0.0)
    trace = ramp([(0, 0), (0.2, 0), (0.5, 15 * DEG), (0.8, 15 * DEG), (1.1, 30 * DEG), (1.3, 30 * DEG)])
    ev = g.update(trace)
    assert [(what, GEARS.names[i]) for _, what, i in ev] == [("leave", "P"), ("enter", "R"), ("leave", "R"), ("enter", "N")]
    # Entering R: at the capture edge 15 - 0.3 * 15 = 10.5 deg, reached at t = 0.2 + 0.3 * 10.5 / 15.
    pos = ev[1][0]
    assert abs(pos * 0.002 - (0.2 + 0.3 * 10.5 / 15)) < 1e-9


def test_gearshift_tracker_hysteresis_no_chatter():
    """A lever jittering across the capture edge enters once and never leaves."""
    g = GearshiftTracker(GEARS, 0.0)
    edge = 15 * DEG - GEARS.capture_rad[1]
    jitter = edge + 0.5 * DEG * np.sin(np.arange(500) * 0.3)
    ev = g.update(np.r_[ramp([(0, 0), (0.1, edge - 0.5 * DEG)]), jitter])
    assert [w for _, w, _ in ev] == ["leave", "enter"]


def test_gearshift_tracker_fast_sweep_in_one_step():
    """One physics step from P to D crosses every detent in order."""
    g = GearshiftTracker(GEARS, 0.0)
    ev = g.update([45 * DEG])
    assert [(w, GEARS.names[i]) for _, w, i in ev] == [
        ("leave", "P"), ("enter", "R"), ("leave", "R"), ("enter", "N"), ("leave", "N"), ("enter", "D")]
    assert np.all(np.diff([p for p, _, _ in ev]) > 0)


def test_ratchet_tracker_counts_pawl_snaps():
    lever = ramp([(0, 0), (1.0, 33 * DEG)])
    # The pawl rises to 9 deg while each pin passes and snaps back 2 deg past the tooth.
    pawl = np.zeros_like(lever)
    for k in range(4):  # teeth at 8, 15, 22, 29 deg are passed below 33 deg
        centre = (8 + 7 * k - 1.5) * DEG
        pawl += 9 * DEG * np.clip(1 - np.abs(lever - centre) / (3.5 * DEG), 0, 1)
    r = RatchetTracker(TEETH, 0.0, 0.0)
    clicks = r.update(lever, pawl)
    assert [t for _, t in clicks] == [1, 2, 3, 4]
    # A pawl bounce at rest does not click again; lowering needs the teeth to re-arm.
    assert r.update(np.full(50, 33 * DEG), 5 * DEG * np.abs(np.sin(np.arange(50) * 0.4))) == []


def test_ratchet_tracker_release_button():
    """Pulled with the pawl held up: silent; letting the button go: one click."""
    r = RatchetTracker(TEETH, 0.0, 0.0)
    lever = ramp([(0, 0), (1.0, 30 * DEG)])
    assert r.update(lever, np.full_like(lever, 25 * DEG)) == []
    clicks = r.update(np.full(20, 30 * DEG), np.linspace(25 * DEG, 0, 20))
    assert [t for _, t in clicks] == [4]


def test_geometry_errors():
    with pytest.raises(ConfigError, match="strictly increasing"):
        GearshiftGeometry(detents_rad=(0.0, 0.2, 0.1, 0.3))
    with pytest.raises(ConfigError, match="capture"):
        GearshiftGeometry(detents_rad=(0.0, 0.1, 0.2, 0.3), capture_fraction=0.5)
    with pytest.raises(ConfigError, match="strictly increasing"):
        RatchetGeometry(teeth_rad=())
    with pytest.raises(ConfigError, match="drop < lift"):
        RatchetGeometry(teeth_rad=(0.1, 0.2), pawl_drop_rad=0.1, pawl_lift_rad=0.05)
    assert TEETH.teeth_engaged(0.0) == 0 and TEETH.teeth_engaged(8 * DEG) == 1 and TEETH.teeth_engaged(60 * DEG) == 7
    assert GEARS.position(14 * DEG) == "R" and GEARS.position(7.5 * DEG) is None


# -- sound material ----------------------------------------------------------------------------------


def test_alarm_loop_keeps_the_beep_rhythm():
    loop = alarm_loop(np.random.default_rng(3))
    beeps = onsets(np.tile(loop, 3), SAMPLE_RATE, threshold=0.3, min_gap_s=0.2)
    gaps = np.diff(beeps)
    assert gaps.max() - gaps.min() <= 2  # samples: the wrap keeps the period
    assert abs(np.sqrt(np.mean(loop**2)) - 1.0) < 1e-12


def test_ratchet_clicks_are_short_and_many():
    clicks = ratchet_clicks(np.random.default_rng(4))
    assert len(clicks) >= 5
    assert all(c.size <= round(0.036 * SAMPLE_RATE) + 1 for c in clicks)
    assert np.mean([np.mean(c**2) for c in clicks]) == pytest.approx(1.0)


def test_gearshift_throws_are_single_throws():
    throws = gearshift_throws(np.random.default_rng(5))
    assert len(throws) >= 4
    for x in throws:
        assert 0.2 * SAMPLE_RATE < x.size < 1.0 * SAMPLE_RATE  # a slide (0.08-0.3 s) and a 0.35 s clunk
        assert not np.any(np.convolve(x == 0.0, np.ones(round(0.05 * SAMPLE_RATE)), "valid") == round(0.05 * SAMPLE_RATE))
    assert np.mean([np.mean(x**2) for x in throws]) == pytest.approx(1.0)


# -- the event source on synthetic traces --------------------------------------------------------------


def run_events(seed, requests=True):
    ev = SoundEvents(np.random.default_rng(seed), emitters=EMITTERS, gearshift=GEARS, ratchet=TEETH)
    ev.reset(sample=0, gear_angle=0.0, brake_angle=0.0, pawl_angle=0.0)
    gear = ramp([(0, 0), (0.2, 0), (0.5, 15 * DEG), (0.8, 15 * DEG), (1.1, 30 * DEG), (1.6, 30 * DEG)])
    brake = ramp([(0, 0), (1.6, 20 * DEG)])
    pawl = sum(9 * DEG * np.clip(1 - np.abs(brake - (6.5 + 7 * k) * DEG) / (3.5 * DEG), 0, 1) for k in range(2))
    if requests:
        ev.schedule_call(0.5)
        ev.schedule_key_turn(0.7)
        ev.schedule_horn(1.0)
    out = []
    for k in range(100):
        pos = np.arange(8 * k + 1, 8 * k + 9) * (SAMPLE_RATE * 0.002)
        sl = slice(8 * k, 8 * k + 8)
        out += ev.process(frame_end_sample(k + 1), pos, gear_angles=gear[sl], brake_angles=brake[sl], pawl_angles=pawl[sl])
    return out


def test_events_from_traces_and_requests():
    out = run_events(1)
    kinds = [e.kind for e in out]
    assert kinds.count("alarm_start") == 1 and kinds.count("alarm_stop") == 1
    assert [e.detail for e in out if e.kind == "gear_change"] == ["R", "N"]
    assert [e.detail for e in out if e.kind == "ratchet_click"] == ["1", "2"]
    assert {e.kind: e.label for e in out} == {
        "alarm_start": "reverse_alarm", "alarm_stop": "reverse_alarm", "gear_change": "gearshift", "ratchet_click": "ratchet",
        "key_turn": "key_turning", "voice_call": "human_voice", "distractor": "car_horn"}
    start = next(e for e in out if e.kind == "alarm_start")
    assert start.sample == round((0.2 + 0.3 * 10.5 / 15) * SAMPLE_RATE) and start.loop and start.source == "alarm"
    assert next(e for e in out if e.kind == "voice_call").sample == 22050
    assert [e.sample for e in out] == sorted(e.sample for e in out)
    for e in out:
        if e.kind != "alarm_stop":
            assert e.signal.ndim == 1 and np.all(np.isfinite(e.signal))


def test_same_seed_same_events_and_audio():
    a, b, c = run_events(7), run_events(7), run_events(8)
    assert a == b
    assert all(np.array_equal(x.signal, y.signal) for x, y in zip(a, b) if x.signal is not None)
    assert [e.sample for e in a] == [e.sample for e in c]  # times come from physics, not the seed
    assert not all(np.array_equal(x.signal, y.signal) for x, y in zip(a, c) if x.signal is not None)


def test_emitters_draw_independently():
    """An emitter's sounds do not depend on the requests made to other emitters."""
    a = [e for e in run_events(5, requests=True) if e.source in ("alarm", "ratchet", "gearshift")]
    b = [e for e in run_events(5, requests=False) if e.source in ("alarm", "ratchet", "gearshift")]
    assert a == b and all(np.array_equal(x.signal, y.signal) for x, y in zip(a, b) if x.signal is not None)


def test_request_errors():
    ev = SoundEvents(np.random.default_rng(0), emitters=["voice", "loudspeaker"])
    ev.reset(sample=44100)
    with pytest.raises(ConfigError, match="in the past"):
        ev.schedule_call(0.5)
    with pytest.raises(ConfigError, match="no site 'car/ignition'"):
        ev.schedule_key_turn(2.0)
    with pytest.raises(ConfigError, match="unknown sound class"):
        ev.schedule_distractor(2.0, "trumpet")
    with pytest.raises(ConfigError, match="1-D"):
        ev.schedule_call(2.0, signal=np.zeros((2, 3)))
    with pytest.raises(ConfigError, match="unknown emitters"):
        SoundEvents(np.random.default_rng(0), emitters=["tuba"])
    with pytest.raises(ConfigError, match="must be -20..160"):
        EventsConfig(voice_db=200.0)
    # The room's loudspeaker plays any class as a distractor.
    s = ev.schedule_distractor(1.5, "ratchet")
    (e,) = ev.process(s + 706, [s + 706.0])
    assert (e.kind, e.label, e.source, e.sample) == ("distractor", "ratchet", "loudspeaker", s)


def test_draw_is_the_emitters_own_stream():
    """``draw`` gives the sounds an emitter's requests would have played, in turn."""
    requested = SoundEvents(np.random.default_rng(3), emitters=["voice", "loudspeaker"])
    drawn = SoundEvents(np.random.default_rng(3), emitters=["voice", "loudspeaker"])
    for ev in (requested, drawn):
        ev.reset(sample=0)
    s1 = requested.schedule_distractor(0.1, "human_voice")
    s2 = requested.schedule_distractor(0.2, "key_turning")
    played = requested.process(s2 + 706, [s2 + 706.0])
    assert [e.sample for e in played] == [s1, s2]
    x1, x2 = drawn.draw("loudspeaker", "human_voice"), drawn.draw("loudspeaker", "key_turning")
    assert np.array_equal(x1, played[0].signal) and np.array_equal(x2, played[1].signal)
    # Another emitter's generator is another stream, untouched by the loudspeaker's draws.
    assert not np.array_equal(drawn.draw("voice", "human_voice"), x1)
    assert np.sqrt(np.mean(x1**2)) == pytest.approx(1.0, rel=1e-6)
    with pytest.raises(ConfigError, match="unknown emitter 'tuba'"):
        drawn.draw("tuba", "human_voice")
    with pytest.raises(ConfigError, match="no site 'car/ignition'"):
        drawn.draw("ignition", "key_turning")
    with pytest.raises(ConfigError, match="unknown sound class"):
        drawn.draw("loudspeaker", "trumpet")


# -- ego-noise -------------------------------------------------------------------------------------


def test_ego_noise_level_rises_with_speed():
    ego = MotorEgoNoise(np.ones(3), np.full(3, 10.0))

    def level(speeds, efforts=(0.0, 0.0, 0.0)):
        ego.set_activity(speeds, efforts)
        return ego.level_db

    assert level(np.zeros(3)) == -np.inf and ego.pressure_rms == 0.0
    assert np.all(ego(706, np.random.default_rng(0)) == 0.0)  # at rest: silent
    levels = [level([v, 0.0, 0.0]) for v in (0.25, 0.5, 1.0, 2.0)]
    assert np.allclose(np.diff(levels), 20 * np.log10(2))  # +6 dB per doubling of speed
    assert levels[2] == pytest.approx(EgoNoiseConfig().level_db)
    assert level([1.0, 1.0, 0.0]) == pytest.approx(levels[2] + 10 * np.log10(2))  # two motors: +3 dB
    assert level([1.0, 0.0, 0.0], [10.0, 0.0, 0.0]) == pytest.approx(levels[2] + 20 * np.log10(2))
    assert level([1e6, 0.0, 0.0]) == EgoNoiseConfig().max_level_db


def test_ego_noise_level_and_spectrum_match_the_stream():
    ego = MotorEgoNoise(np.ones(2), np.full(2, 10.0))
    ego.set_activity([2.0, 1.0], [0.0, 0.0])
    level = ego.level_db
    rng = np.random.default_rng(0)
    x = np.concatenate([ego(706, rng) for _ in range(700)], axis=1)[:, 706:]
    measured = 20 * np.log10(np.sqrt(np.mean(x**2, axis=1)) / 20e-6)
    assert np.all(np.abs(measured - level) < 0.3)
    assert 0.4 < np.corrcoef(x)[0, 1] < 0.6  # coherence 0.5
    n = 2048
    frames = x[0, : x.shape[1] // n * n].reshape(-1, n) * signal.get_window("hamming", n)
    empirical = np.mean(np.abs(np.fft.rfft(frames, axis=1)) ** 2, axis=0)
    expected = ego.expected_power_spectrum(n, "hamming")
    # The unit spectrum times the level squared is the same spectrum, bit for bit.
    assert np.array_equal(ego.unit_power_spectrum(n, "hamming") * ego.pressure_rms**2, expected)
    band = slice(20, 560)  # 430 Hz .. 12 kHz, where the noise is well above numerical floor
    ratio = empirical[band] / expected[band]
    assert 0.85 < np.median(ratio) < 1.15 and 0.9 < empirical.sum() / expected.sum() < 1.1
    whine = round(EgoNoiseConfig().whine_hz / (SAMPLE_RATE / n))
    assert expected[whine] > 5 * expected[whine - 12]  # the whine peak stands out


def test_ego_noise_errors():
    with pytest.raises(ConfigError, match="level_db"):
        EgoNoiseConfig(level_db=-5.0)
    with pytest.raises(ConfigError, match="band_hz"):
        EgoNoiseConfig(band_hz=(500.0, 100.0))
    ego = MotorEgoNoise(np.ones(2), np.ones(2))
    with pytest.raises(ConfigError, match="expected 2 speeds"):
        ego.set_activity(np.zeros(3), np.zeros(3))
    with pytest.raises(ConfigError, match="not finite"):
        ego.set_activity([np.nan, 0.0], [0.0, 0.0])
    with pytest.raises(ConfigError, match="window"):
        ego.expected_power_spectrum(2048, np.ones(10))
    with pytest.raises(ConfigError, match="window"):
        ego.unit_power_spectrum(2048, np.ones(10))
    with pytest.raises(ConfigError, match="from_view"):
        ego.update(None)


# -- the real cabin: physics drives the events ---------------------------------------------------------

def hand(c, joint, target, kp, kd):
    """A hand on a lever: a PD torque (N m) on its hinge toward ``target`` (rad)."""
    dof = c.model.joint(joint).dofadr[0]
    c.data.qfrc_applied[dof] = kp * (target - c.view.joint_angle(joint)) - kd * c.view.joint_velocity(joint)


def let_go(c, joint):
    c.data.qfrc_applied[c.model.joint(joint).dofadr[0]] = 0.0


def cabin_without_audio(seed=0, **config):
    model, data, _ = scenes.load_scene("cabin", config=scenes.CabinConfig(**config))
    return Coupling(model, data, None, rng=np.random.default_rng(seed))


def test_gearshift_p_r_n_one_alarm_start_and_stop():
    c = cabin_without_audio()
    assert c.view.gearshift_position() == "P"
    events = []
    for k in range(int(2.6 * 62.5)):
        t = k / 62.5
        hand(c, names.GEARSHIFT_JOINT, np.interp(t, [0, 0.3, 1.0, 1.6, 2.3], [0, 0, 15, 15, 30]) * DEG, 10.0, 0.3)
        events += c.advance()
    assert c.view.gearshift_position() == "N"
    kinds = [e.kind for e in events]
    assert kinds.count("alarm_start") == 1 and kinds.count("alarm_stop") == 1
    assert [e.detail for e in events if e.kind == "gear_change"] == ["R", "N"]
    start, stop = (next(e for e in events if e.kind == k) for k in ("alarm_start", "alarm_stop"))
    assert start.sample < stop.sample and start.label == stop.label == "reverse_alarm" and start.source == "alarm"
    assert not c.events.alarm_on


def test_lever_resting_in_reverse_starts_the_alarm_at_once():
    c = cabin_without_audio(gear="R")
    events = c.advance()
    assert [(e.kind, e.sample) for e in events] == [("alarm_start", 0)]


@pytest.mark.parametrize("k", [2, 5])
def test_brake_pulled_over_k_teeth_gives_k_clicks(k):
    c = cabin_without_audio()
    top = np.rad2deg(c.view.ratchet_geometry.teeth_rad[k - 1]) + 3.5  # between tooth k and k + 1
    clicks = []
    for step in range(int(3.0 * 62.5)):
        t = step / 62.5
        if t < 2.2:
            hand(c, names.BRAKE_JOINT, np.interp(t, [0, 0.2, 1.8], [0, 0, top]) * DEG, 60.0, 1.0)
        else:
            let_go(c, names.BRAKE_JOINT)  # the pawl holds the lever on tooth k
        clicks += [e for e in c.advance() if e.kind == "ratchet_click"]
    assert c.view.brake_teeth_engaged() == k, np.rad2deg(c.view.brake_angle())
    assert [e.detail for e in clicks] == [str(i) for i in range(1, k + 1)]
    assert all(e.label == "ratchet" and e.source == "ratchet" for e in clicks)


def test_scene_same_seed_same_event_times_and_audio(kemar):
    def episode(seed):
        c = Coupling.from_scene("cabin", rng=np.random.default_rng(seed), hrtf=kemar)
        c.events.schedule_horn(0.4)
        c.events.schedule_key_turn(0.9)
        events, audio = [], []
        for step in range(int(1.6 * 62.5)):
            t = step / 62.5
            hand(c, names.GEARSHIFT_JOINT, np.interp(t, [0, 0.1, 0.8], [0, 0, 15]) * DEG, 10.0, 0.3)
            hand(c, names.BRAKE_JOINT, np.interp(t, [0, 0.1, 1.5], [0, 0, 20]) * DEG, 20.0, 0.5)
            events += c.advance()
            audio.append(c.render())
        return events, np.concatenate(audio, axis=1)

    (ea, xa), (eb, xb), (ec, xc) = episode(3), episode(3), episode(4)
    assert ea == eb and np.array_equal(xa, xb)
    assert {e.kind for e in ea} >= {"gear_change", "alarm_start", "ratchet_click", "distractor", "key_turn"}
    assert [e.sample for e in ea] == [e.sample for e in ec]  # times come from physics and requests
    assert not np.array_equal(xa, xc)  # the sounds (and noise) come from the seed
