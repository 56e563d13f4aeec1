"""The emitters' sounds: each emitter's own generator, and when it is drawn.

Every emitter draws its sounds with :func:`acoustic_sim.acoustics.sounds.generate` from its
own generator, spawned in a fixed order (:data:`~acoustic_sim.world.events.emitters.EMITTERS`)
from the one passed in: the same seed and the same physics give the same samples, and one
emitter's sounds do not depend on what the others did. The mechanisms' signals (one beeper,
one ratchet's clicks, one lever's throws; :mod:`acoustic_sim.acoustics.sounds.cutting`) are drawn
once, at their first event or at a reset with ``prefetch``; a requested sound is drawn when
first needed (at once with ``prefetch``), always in request order, so the signals are the
same either way.
"""

from __future__ import annotations

import collections

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.sounds.cutting import alarm_loop, gearshift_throws, ratchet_clicks
from acoustic_sim.world.events.emitters import EMITTERS, EventsConfig


class Deferred:
    """A requested sound's signal, drawn from its emitter's generator when first needed."""

    __slots__ = ("emitter", "label", "signal")

    def __init__(self, emitter: str, label: str) -> None:
        self.emitter, self.label = emitter, label
        self.signal: np.ndarray | None = None


class EmitterDraws:
    """The signals of every emitter, each drawn from the emitter's own generator.

    Parameters
    ----------
    rng : numpy.random.Generator
        Spawns one generator per emitter (in :data:`EMITTERS` order), used for nothing else.
    config : EventsConfig
        The draws' lengths (``alarm_draw_s``, ``click_s``, ``gearshift_draw_s``) and ``prefetch``.
    sample_rate : int
        Hz of the signals.
    """

    def __init__(self, rng: np.random.Generator, *, config: EventsConfig, sample_rate: int) -> None:
        self.config = config
        self.sample_rate = sample_rate
        self._rngs = dict(zip(EMITTERS, rng.spawn(len(EMITTERS))))
        self._alarm_loop: np.ndarray | None = None
        self._clicks: list[np.ndarray] | None = None
        self._n_clicks = 0
        self._throws: list[np.ndarray] | None = None
        self._n_throws = 0
        self._deferred: dict[str, collections.deque] = {}

    # Each mechanism's signal, drawn once from its emitter's own generator (which nothing else
    # draws from), whenever that is: the same signal at reset or at the first event.
    def beeper(self) -> np.ndarray:
        """The reverse alarm's loop (unit RMS)."""
        if self._alarm_loop is None:
            self._alarm_loop = alarm_loop(self._rngs["alarm"], seconds=self.config.alarm_draw_s, sample_rate=self.sample_rate)
        return self._alarm_loop

    def ratchet_clicks(self) -> list[np.ndarray]:
        """The ratchet's clicks (mean power 1)."""
        if self._clicks is None:
            self._clicks = ratchet_clicks(self._rngs["ratchet"], click_s=self.config.click_s, sample_rate=self.sample_rate)
        return self._clicks

    def gear_throws(self) -> list[np.ndarray]:
        """The gearshift's throws (mean power 1)."""
        if self._throws is None:
            self._throws = gearshift_throws(self._rngs["gearshift"], seconds=self.config.gearshift_draw_s,
                                            sample_rate=self.sample_rate)
        return self._throws

    def next_click(self) -> np.ndarray:
        """The ratchet's next click: its clicks play in turn, one per tooth."""
        clicks = self.ratchet_clicks()
        x = clicks[self._n_clicks % len(clicks)]
        self._n_clicks += 1
        return x

    def next_throw(self) -> np.ndarray:
        """The gearshift's next throw: its throws play in turn, one per gear change."""
        throws = self.gear_throws()
        x = throws[self._n_throws % len(throws)]
        self._n_throws += 1
        return x

    # Requested sounds: one natural instance each, drawn in request order.
    def later(self, emitter: str, label: str) -> Deferred:
        """A requested sound's signal, drawn when first needed (at once with ``prefetch``)."""
        d = Deferred(emitter, label)
        self._deferred.setdefault(emitter, collections.deque()).append(d)
        if self.config.prefetch:
            self.resolve(d)
        return d

    def resolve(self, d: Deferred) -> np.ndarray:
        """``d``'s signal: the emitter's earlier requests are drawn first, so each request gets
        the draw it would have had when it was made."""
        queue = self._deferred[d.emitter]
        while d.signal is None:
            first = queue.popleft()
            first.signal = self._draw(first.emitter, first.label)
        return d.signal

    def draw(self, emitter: str, label: str) -> np.ndarray:
        """A fresh instance of ``label`` from ``emitter``'s generator, after its pending requests."""
        pending = self._deferred.get(emitter)
        if pending:  # the earlier requests draw first, as when they were made
            self.resolve(pending[-1])
        return self._draw(emitter, label)

    def _draw(self, emitter: str, label: str) -> np.ndarray:
        # Requested sounds are drawn when requested (a task's reset), not in a control step.
        return sounds.generate(label, self._rngs[emitter], sample_rate=self.sample_rate)
