"""The hearing loop (acoustic_sim.loop): one StepHearing per control step, the warm-up, the
one owner of the scheduled sounds, and the one law for sounds from outside the room."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE

ROOT = Path(__file__).resolve().parents[1]


def _loop(scene: str = "room", **kwargs):
    from acoustic_sim.acoustics.microphone import Microphone
    from acoustic_sim.loop import HearingLoop
    from acoustic_sim.world.coupling import Coupling
    from tasks.auditory import make_pipeline

    c = Coupling.from_scene(scene, rng=np.random.default_rng(0), **kwargs)
    return HearingLoop(c, Microphone(rng=np.random.default_rng(1)), make_pipeline("fast"))


def test_a_step_hears_one_block_one_percept_and_its_events():
    loop = _loop(ego_noise=False, background=False)
    c = loop.coupling
    burst = np.random.default_rng(2).standard_normal(round(0.1 * SAMPLE_RATE))
    snd = loop.schedule_sound("probe", "car_horn", burst, c.head_position + [0.0, 1.0, 0.0], c.time_s + 0.05, 80.0)
    c.events.schedule_call(c.time_s + 0.08)
    heard, records, sources_seen = [], [], set()
    for _ in range(30):
        h = loop.step()
        heard.append(h)
        records += h.events
        sources_seen |= set(c.renderer.sources)
    for k, h in enumerate(heard, start=1):
        n = h.pressure.shape[1]
        assert n in (705, 706) and h.pressure.shape == h.audio.shape == (2, n) and h.audio.dtype == np.float32
        assert h.frame == k == h.percept.frame and h.time_s == pytest.approx(h.percept.time_s)
        assert h.frame_audio.shape == (2, 2048)
        np.testing.assert_array_equal(h.frame_audio[:, -n:], h.audio)  # the frame ends with the block
        power = h.frame_power()
        assert power.shape == (2, 1025) and np.all(power >= 0)
    assert [r["source"] for r in records] == ["task/probe", "voice"]
    assert records[0]["time_s"] == snd.start / SAMPLE_RATE
    assert any(ev.source == "voice" for h in heard for ev in h.world_events)
    assert {"task/probe", "voice"} <= sources_seen  # the scheduled sound went through the renderer
    assert loop.last is heard[-1]
    with pytest.raises(dataclasses.FrozenInstanceError):
        heard[0].percept = None


def test_warm_up_measures_the_ambient_noise_and_forgets_what_sounded():
    from acoustic_sim.loop import microphone_floor

    loop = _loop(ego_noise=False)
    c = loop.coupling
    c.events.schedule_call(0.05)  # heard during the warm-up, then forgotten
    last = loop.warm_up(0.3)
    assert last is loop.last and last.frame == round(0.3 * FRAME_RATE) == c.frame_index
    assert loop.ambient_power.shape == (2, 1025) and np.all(loop.ambient_power >= microphone_floor())
    assert np.any(loop.ambient_power > microphone_floor())  # the room's background is above the microphone's floor
    assert loop.soundscape.sounding() == []
    loop.step()
    np.testing.assert_array_equal(loop.pipeline.noise_power, loop.ambient_power)  # no ego-noise: the room's alone
    assert loop.warm_up(0.0) is None
    with pytest.raises(ConfigError, match="seconds"):
        loop.warm_up(-1.0)


def test_loop_errors():
    from acoustic_sim.acoustics.microphone import Microphone
    from acoustic_sim.loop import HearingLoop
    from acoustic_sim.world.coupling import Coupling
    from acoustic_sim.world.soundscape import Soundscape

    loop = _loop(ego_noise=False, background=False)
    c = loop.coupling
    mic = Microphone(rng=np.random.default_rng(0))
    with pytest.raises(ConfigError, match="renderer"):
        HearingLoop(Coupling(c.model, c.data, None, rng=np.random.default_rng(0)), mic, loop.pipeline)
    other = Coupling.from_scene("room", rng=np.random.default_rng(3), ego_noise=False, background=False)
    with pytest.raises(ConfigError, match="soundscape"):
        HearingLoop(c, mic, loop.pipeline, soundscape=Soundscape(other))


def test_the_env_observes_what_its_loop_heard():
    from tasks.levers import lever_arm_angles
    from tasks.reverse_alarm import ReverseAlarmEnv

    env = ReverseAlarmEnv(profile="fast", audio_obs=True, spectra_obs=True)
    obs, _ = env.reset(seed=5)
    warm = env.hearing.last
    assert warm.frame == round(env.warmup_s * FRAME_RATE) and env.last_percept is warm.percept
    assert env.last_hearing is None and not obs["audio"].any() and not obs["spectra"].any()
    hold = env.layout.action({**env.layout.arm("left", lever_arm_angles("left", 0.0)), "grasp_left": 1.0})
    for _ in range(3):
        obs, _, _, _, info = env.step(hold)
        h = env.last_hearing
        assert h is env.hearing.last and env.last_percept is h.percept and env.last_audio is h.audio
        n = h.audio.shape[1]
        np.testing.assert_array_equal(obs["audio"][:, :n], h.audio)
        np.testing.assert_array_equal(obs["spectra"], h.frame_power().astype(np.float32))
        assert info["events"] == list(h.events) and info["time_s"] == h.time_s
    assert env.soundscape is env.hearing.soundscape
    env.close()


def test_the_outside_law_has_one_implementation():
    """A scheduled sound outside the room and the car horn play by Coupling.through_body."""
    from acoustic_sim.world import names
    from acoustic_sim.world.coupling import Coupling
    from acoustic_sim.world.soundscape import Soundscape
    from tasks.task_sounds import outside_placement

    c = Coupling.from_scene("cabin", rng=np.random.default_rng(0), ego_noise=False, background=False)
    sc = Soundscape(c)
    point = c.head_position + np.array([-3.0, 1.5, 0.0])  # behind the car, outside the cabin
    snd = sc.schedule_sound("car", "reverse_alarm", np.ones(100), point, c.time_s + 0.5, 90.0, outside=True)
    position, level = c.through_body(point, 90.0)
    np.testing.assert_array_equal(snd.position, position)
    assert snd.level_db == level
    p2, l2 = outside_placement(c, point, 90.0)
    np.testing.assert_array_equal(p2, position)
    assert l2 == level
    # The horn: its anchor is the same law, at the horn site, as a level change.
    horn = c.frame.to_room(c.view.site_position(names.HORN_SITE))
    inside, change = c.through_body(horn, 0.0)
    np.testing.assert_array_equal(c.emitter_position("horn"), inside)
    c.events.schedule_horn(c.time_s)
    c.advance()
    sound = c._emitters["horn"].sounds[0]
    from acoustic_sim.frames import db_spl_to_pa

    assert sound.gain == pytest.approx(float(db_spl_to_pa(c.events.config.horn_db + change)), rel=1e-12)
    # ... and the law's arithmetic (transmission loss, spreading) is written nowhere else.
    users = [p.relative_to(ROOT).as_posix() for pkg in ("acoustic_sim", "tasks", "policies", "apps")
             for p in sorted((ROOT / pkg).rglob("*.py")) for node in ast.walk(ast.parse(p.read_text()))
             if isinstance(node, ast.Attribute) and node.attr == "transmission_loss_db"]
    assert users == ["acoustic_sim/world/coupling.py"]


def _drivers(root: Path) -> list[str]:
    """Calls in ``root/tasks/*.py`` that drive the loop's parts themselves (``file:line .name()``)."""
    loop_only = {"advance", "begin_block", "end_block", "render_block", "add_source", "remove_source", "process",
                 "set_noise_power", "warm_up"}
    found = []
    for p in sorted((root / "tasks").glob("*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
                f = node.func
                owner = f.value.attr if isinstance(f.value, ast.Attribute) else getattr(f.value, "id", "")
                if f.attr in loop_only and owner != "hearing" or f.attr == "render" and owner in ("c", "coupling"):
                    found.append(f"{p.name}:{node.lineno} .{f.attr}()")
    return found


def test_no_task_code_drives_the_renderer_or_the_pipeline():
    """The env's step goes through the loop: tasks/ never renders, processes or adds a source."""
    found = _drivers(ROOT)
    assert not found, found


def test_the_driver_check_sees_a_hand_rolled_step(tmp_path):
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "x.py").write_text("def step(self, c):\n    c.advance()\n    self.pipeline.process(c.render())\n"
                                             "    self.hearing.warm_up(0.5)\n")
    assert _drivers(tmp_path) == ["x.py:2 .advance()", "x.py:3 .process()", "x.py:3 .render()"]
