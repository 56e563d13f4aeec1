"""Sounds synthesized when first heard (the default) or when requested (``prefetch``): the same
episodes, bit for bit. The deferral only moves when each emitter's generator is drawn, never
the order, so every observation, reward and event must match."""

import dataclasses

import numpy as np
import pytest

from acoustic_sim.world import events
from apps import runner
from policies import make_policy


def _episode(task: str, seed: int, steps: int = 400):
    env = runner.make_env(task, profile="fast")
    try:
        policy = make_policy("oracle", env)
        obs, info = env.reset(seed=seed)
        policy.reset(obs, info, seed)
        trace = [obs]
        kinds = []
        for _ in range(steps):
            obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
            trace.append({**obs, "reward": np.float64(reward)})
            kinds += [(e["kind"], e["time_s"]) for e in info["events"]]
            if terminated or truncated:
                break
        return trace, kinds, info["outcome"]
    finally:
        env.close()


@pytest.mark.parametrize("task, seed", [("reverse-alarm", 3), ("parking-brake", 4), ("call-response", 8)])
def test_prefetch_and_deferred_sounds_give_the_same_episode(task, seed, monkeypatch):
    lazy = _episode(task, seed)
    init = events.SoundEvents.__init__

    def prefetching(self, rng, *, config=None, **kwargs):
        init(self, rng, config=dataclasses.replace(config or events.EventsConfig(), prefetch=True), **kwargs)

    monkeypatch.setattr(events.SoundEvents, "__init__", prefetching)
    eager = _episode(task, seed)
    assert lazy[1] == eager[1] and lazy[2] == eager[2]
    assert any(k in ("alarm_start", "ratchet_click", "voice_call") for k, _ in lazy[1]), lazy[1]
    if task == "call-response":  # seed 8: the loudspeaker plays (deferred with draw_later) before the call
        assert ("distractor", "voice_call") == tuple(k for k, _ in lazy[1][:2]), lazy[1]
    assert len(lazy[0]) == len(eager[0])
    for a, b in zip(lazy[0], eager[0]):
        assert a.keys() == b.keys()
        for key in a:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_a_draw_after_deferred_requests_gets_what_it_got_before():
    """An emitter's direct draw takes its place after the requests already made."""
    def run(prefetch: bool):
        ev = events.SoundEvents(np.random.default_rng(7), emitters=["loudspeaker"],
                                config=events.EventsConfig(prefetch=prefetch))
        ev.reset(sample=0)
        ev.schedule_distractor(0.5, "key_turning")
        direct = ev.draw("loudspeaker", "car_horn")
        out = ev.process(round(0.6 * ev.sample_rate), [0.6 * ev.sample_rate])
        return direct, out[0].signal

    for a, b in zip(run(False), run(True)):
        np.testing.assert_array_equal(a, b)


def test_draw_later_keeps_the_request_order():
    """Deferred draws resolved in any order get the signals of draws made in request order."""
    def ev():
        e = events.SoundEvents(np.random.default_rng(3), emitters=["loudspeaker"])
        e.reset(sample=0)
        return e

    eager = ev()
    a, b = eager.draw("loudspeaker", "key_turning"), eager.draw("loudspeaker", "car_horn")
    lazy = ev()
    la, lb = lazy.draw_later("loudspeaker", "key_turning"), lazy.draw_later("loudspeaker", "car_horn")
    np.testing.assert_array_equal(lb(), b)
    np.testing.assert_array_equal(la(), a)
    with pytest.raises(Exception, match="unknown sound class"):
        lazy.draw_later("loudspeaker", "kazoo")
