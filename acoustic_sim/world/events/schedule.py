"""The event source: mechanism traces and requests in, :class:`SoundEvent` s out, block by block.

Requests (a call, a key turn, a distractor) are scheduled at a time (s) on the project
clock; the mechanisms' crossings (:mod:`~acoustic_sim.world.events.crossings`) are placed
at their interpolated moment, rounded to the nearest sample, so a sound starts within a
sample of it. Every event carries its start sample (the master clock), its kind, its sound
class and the emitter it plays from; its signal comes from
:class:`~acoustic_sim.world.events.draws.EmitterDraws`.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.render_source import mono_signal
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE
from acoustic_sim.world.events.crossings import GearshiftTracker, RatchetTracker
from acoustic_sim.world.events.draws import Deferred, EmitterDraws
from acoustic_sim.world.events.emitters import EMITTERS, EventsConfig, SoundEvent
from acoustic_sim.world.lever_geometry import GearshiftGeometry, RatchetGeometry


class SoundEvents:
    """Turn mechanism traces and requests into :class:`SoundEvent` s, block by block.

    Parameters
    ----------
    rng : numpy.random.Generator
        Spawns one generator per emitter (in :data:`EMITTERS` order), used for nothing else.
    emitters : iterable of str
        The emitters this scene has (keys of :data:`EMITTERS`).
    gearshift : GearshiftGeometry, optional
        The gearshift's detents (cabin scenes); no alarm or gear changes without it.
    ratchet : RatchetGeometry, optional
        The brake's ratchet (cabin scenes); no clicks without it.
    config : EventsConfig, optional
    sample_rate : int
        Hz of the project clock.

    Notes
    -----
    Call :meth:`reset` with the initial angles, then :meth:`process` once per control
    block with the angles after each physics step. :meth:`from_view` builds one for a world.
    """

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        emitters,
        gearshift: GearshiftGeometry | None = None,
        ratchet: RatchetGeometry | None = None,
        config: EventsConfig | None = None,
        sample_rate: int = SAMPLE_RATE,
    ) -> None:
        if not isinstance(rng, np.random.Generator):
            raise ConfigError(f"SoundEvents needs a numpy.random.Generator, got {type(rng).__name__}")
        self.emitters = frozenset(emitters)
        unknown = self.emitters - set(EMITTERS)
        if unknown:
            raise ConfigError(f"unknown emitters {sorted(unknown)}; valid: {sorted(EMITTERS)}")
        self.config = config or EventsConfig()
        self.sample_rate = int(sample_rate)
        self._draws = EmitterDraws(rng, config=self.config, sample_rate=self.sample_rate)
        self.gearshift = GearshiftTracker(gearshift, 0.0) if gearshift is not None else None
        self.ratchet = RatchetTracker(ratchet, 0.0, 0.0) if ratchet is not None else None
        if self.gearshift is not None and "R" not in gearshift.names:
            raise ConfigError(f"the gearshift has no reverse gear 'R': gears {gearshift.names}")
        self._queue: list[tuple[int, int, str, str, str, np.ndarray | Deferred | None]] = []
        self._order = 0
        self.next_sample = 0
        """First sample of the next block to process (requests before it are refused)."""
        self.alarm_on = False
        """Whether the reverse alarm is sounding."""
        self.log: list[SoundEvent] = []
        """Every event so far, in order."""

    @classmethod
    def from_view(cls, view, rng: np.random.Generator, config: EventsConfig | None = None, *,
                  sample_rate: int = SAMPLE_RATE) -> SoundEvents:
        """Events for the world seen by ``view``: the emitters whose anchor sites exist,
        and the cabin's mechanisms when it has them. Call :meth:`reset` before use."""
        present = [e.name for e in EMITTERS.values() if view.has_site(e.anchor)]
        return cls(rng, emitters=present, gearshift=view.gearshift_geometry, ratchet=view.ratchet_geometry,
                   config=config, sample_rate=sample_rate)

    def reset(self, *, sample: int, gear_angle: float | None = None, brake_angle: float | None = None,
              pawl_angle: float | None = None) -> None:
        """Start at ``sample`` (the next block's first) with the mechanisms' current angles (rad).

        Scheduled requests and the log are cleared; the alarm is on if the lever rests in R
        (an ``alarm_start`` is then emitted at ``sample`` by the next :meth:`process`).
        """
        self.next_sample = int(sample)
        self._queue.clear()
        self.log = []
        self.alarm_on = False
        if self.gearshift is not None:
            if gear_angle is None:
                raise ConfigError("SoundEvents.reset: this scene has a gearshift; pass gear_angle (rad)")
            self.gearshift.reset(gear_angle)
            if self.gearshift.gear == self.gearshift.geometry.names.index("R") and "alarm" in self.emitters:
                self._push(self.next_sample, "alarm_start", "alarm", "R")
        if self.ratchet is not None:
            if brake_angle is None or pawl_angle is None:
                raise ConfigError("SoundEvents.reset: this scene has a parking brake; pass brake_angle and pawl_angle (rad)")
            self.ratchet.reset(brake_angle, pawl_angle)
        if self.config.prefetch:  # drawn here rather than at their first event: no control step pays
            if self.gearshift is not None and "alarm" in self.emitters:
                self._draws.beeper()
            if self.ratchet is not None and "ratchet" in self.emitters:
                self._draws.ratchet_clicks()
            if self.gearshift is not None and "gearshift" in self.emitters:
                self._draws.gear_throws()

    # -- requests -------------------------------------------------------------------------------
    def _request_sample(self, t: float | None, what: str) -> int:
        if t is None:
            return self.next_sample
        if not np.isfinite(t):
            raise ConfigError(f"{what}: time must be a finite number of seconds, got {t}")
        s = round(t * self.sample_rate)
        if s < self.next_sample:
            raise ConfigError(
                f"{what}: t = {t:.4f} s is in the past (the next block starts at {self.next_sample / self.sample_rate:.4f} s)"
            )
        return s

    def _need_emitter(self, name: str, what: str) -> None:
        if name not in self.emitters:
            raise ConfigError(f"{what}: this scene has no site {EMITTERS[name].anchor!r} to sound from")

    def _signal(self, signal, what: str) -> np.ndarray | None:
        if signal is None:
            return None
        return mono_signal(signal, what)

    def schedule_call(self, t: float | None = None, *, signal=None) -> int:
        """The person calls out at time ``t`` (s, project clock; default: the next block).

        Parameters
        ----------
        t : float, optional
            Start time in s; not before the next block.
        signal : array_like, optional
            A unit-RMS mono signal at the project rate (e.g. a recording); default a fresh
            ``human_voice`` instance.

        Returns
        -------
        int
            The start sample.
        """
        self._need_emitter("voice", "schedule_call")
        s = self._request_sample(t, "schedule_call")
        x = self._signal(signal, "schedule_call")
        self._push(s, "voice_call", "voice", "", x if x is not None else self._draws.later("voice", "human_voice"))
        return s

    def schedule_key_turn(self, t: float | None = None, *, signal=None) -> int:
        """The ignition key turns at time ``t`` (s); see :meth:`schedule_call`."""
        self._need_emitter("ignition", "schedule_key_turn")
        s = self._request_sample(t, "schedule_key_turn")
        x = self._signal(signal, "schedule_key_turn")
        self._push(s, "key_turn", "ignition", "", x if x is not None else self._draws.later("ignition", "key_turning"))
        return s

    def schedule_distractor(self, t: float | None = None, label: str = "car_horn", *, signal=None) -> int:
        """A distractor sound at time ``t`` (s): the car horn outside the cabin, or the
        room's loudspeaker playing ``label`` (any sound class); see :meth:`schedule_call`."""
        if label not in sounds.SOUND_CLASSES:
            raise ConfigError(f"schedule_distractor: unknown sound class {label!r}; valid: {', '.join(sounds.SOUND_CLASSES)}")
        emitter = "horn" if "horn" in self.emitters else "loudspeaker"
        self._need_emitter(emitter, "schedule_distractor")
        if emitter == "horn" and label != "car_horn":
            raise ConfigError(f"schedule_distractor: the cabin's outside distractor is the car horn, not {label!r}")
        s = self._request_sample(t, "schedule_distractor")
        x = self._signal(signal, "schedule_distractor")
        self._push(s, "distractor", emitter, label, x if x is not None else self._draws.later(emitter, label))
        return s

    def schedule_horn(self, t: float | None = None, *, signal=None) -> int:
        """A car horn at time ``t`` (s): outside the cabin, or from the room's loudspeaker."""
        return self.schedule_distractor(t, "car_horn", signal=signal)

    def draw(self, emitter: str, label: str) -> np.ndarray:
        """A fresh natural instance of sound class ``label`` from ``emitter``'s own generator.

        What a request of that emitter plays when it passes no signal of its own: the next
        draw of the same stream. For a caller that plays an emitter's sounds itself (a task
        placing the room loudspeaker's sounds with
        :meth:`tasks.base.HearingTaskEnv.schedule_sound`) and wants the sounds the
        emitter would have made.

        Parameters
        ----------
        emitter : str
            One of this scene's emitters (:attr:`emitters`).
        label : str
            A sound class (``sounds.SOUND_CLASSES``).

        Returns
        -------
        numpy.ndarray, shape (n,)
            Unit-RMS mono signal at :attr:`sample_rate`.

        Raises
        ------
        ConfigError
            If the scene has no such emitter or the class is unknown.
        """
        self._check_draw(emitter, label, "draw")
        return self._draws.draw(emitter, label)

    def draw_later(self, emitter: str, label: str):
        """:meth:`draw`, deferred: a zero-argument callable that gives the same signal when
        called (at once with ``prefetch``), which a scheduled sound calls when it starts
        (:meth:`acoustic_sim.world.soundscape.Soundscape.schedule_sound`). Raises as :meth:`draw`."""
        self._check_draw(emitter, label, "draw_later")
        d = self._draws.later(emitter, label)
        return lambda: self._draws.resolve(d)

    def _check_draw(self, emitter: str, label: str, what: str) -> None:
        if emitter not in EMITTERS:
            raise ConfigError(f"{what}: unknown emitter {emitter!r}; valid: {', '.join(EMITTERS)}")
        self._need_emitter(emitter, what)
        if label not in sounds.SOUND_CLASSES:
            raise ConfigError(f"{what}: unknown sound class {label!r}; valid: {', '.join(sounds.SOUND_CLASSES)}")

    def _push(self, sample: int, kind: str, emitter: str, detail: str, signal: np.ndarray | None = None) -> None:
        self._order += 1
        heapq.heappush(self._queue, (sample, self._order, kind, emitter, detail, signal))

    # -- processing -----------------------------------------------------------------------------
    def process(self, block_end: int, positions, *, gear_angles=None, brake_angles=None, pawl_angles=None) -> list[SoundEvent]:
        """Events whose start falls in the block ``[next_sample, block_end)``.

        Parameters
        ----------
        block_end : int
            First sample after the block.
        positions : array_like, shape (n,)
            Sample position (float, project clock) at the end of each physics step of the
            block; the trace's previous sample is at the block start.
        gear_angles, brake_angles, pawl_angles : array_like, shape (n,), optional
            Hinge angles (rad) of the gearshift, the brake lever and the ratchet pawl after
            each physics step; required when the scene has the mechanism.

        Returns
        -------
        list of SoundEvent
            In time order (ties in the order they arose).
        """
        b0, b1 = self.next_sample, int(block_end)
        if b1 <= b0:
            raise ConfigError(f"SoundEvents.process: block end {b1} is not after its start {b0}")
        pos = [float(b0), *(float(v) for v in positions)]
        n = len(pos) - 1
        for what, trace in (("gear_angles", gear_angles), ("brake_angles", brake_angles), ("pawl_angles", pawl_angles)):
            if trace is not None and len(trace) != n:
                raise ConfigError(f"SoundEvents.process: {what} has {len(trace)} samples for {n} physics steps")

        def sample_at(p: float) -> int:
            # Trace position p in (0, n] lies between pos[floor(p)] and pos[floor(p) + 1].
            k = min(int(p), n - 1)
            at = pos[k] + (p - k) * (pos[k + 1] - pos[k])
            return min(max(math.floor(at + 0.5), b0), b1 - 1)

        if self.gearshift is not None:
            if gear_angles is None:
                raise ConfigError("SoundEvents.process: this scene has a gearshift; pass gear_angles")
            r = self.gearshift.geometry.names.index("R")
            for p, what, g in self.gearshift.update(gear_angles):
                s = sample_at(p)
                name = self.gearshift.geometry.names[g]
                # A scene without the knob or speaker site keeps the state but stays silent.
                if what == "enter":
                    if g != self.gearshift.last_gear and "gearshift" in self.emitters:
                        self._push(s, "gear_change", "gearshift", name)
                    self.gearshift.last_gear = g
                    if g == r and "alarm" in self.emitters:
                        self._push(s + round(self.config.alarm_delay_s * self.sample_rate), "alarm_start", "alarm", name)
                elif g == r and "alarm" in self.emitters:
                    self._cancel_pending("alarm_start", after=s)  # left R before the relay closed
                    self._push(s, "alarm_stop", "alarm", name)
        if self.ratchet is not None:
            if brake_angles is None or pawl_angles is None:
                raise ConfigError("SoundEvents.process: this scene has a parking brake; pass brake_angles and pawl_angles")
            for p, tooth in self.ratchet.update(brake_angles, pawl_angles):
                if "ratchet" in self.emitters:
                    self._push(sample_at(p), "ratchet_click", "ratchet", str(tooth))
        out = []
        while self._queue and self._queue[0][0] < b1:
            sample, _, kind, emitter, detail, signal = heapq.heappop(self._queue)
            if isinstance(signal, Deferred):
                signal = self._draws.resolve(signal)
            ev = self._make(kind, emitter, max(sample, b0), detail, signal)
            if ev is not None:
                out.append(ev)
        self.next_sample = b1
        self.log.extend(out)
        return out

    def _cancel_pending(self, kind: str, *, after: int) -> None:
        """Drop the queued ``kind`` requests due after sample ``after``."""
        kept = [q for q in self._queue if not (q[2] == kind and q[0] > after)]
        if len(kept) != len(self._queue):
            self._queue[:] = kept
            heapq.heapify(self._queue)

    def _make(self, kind: str, emitter: str, sample: int, detail: str, signal: np.ndarray | None) -> SoundEvent | None:
        c = self.config
        if kind == "alarm_start":
            if self.alarm_on:
                return None
            self.alarm_on = True
            return SoundEvent(kind, "reverse_alarm", emitter, sample, c.alarm_db, detail, self._draws.beeper(), loop=True)
        if kind == "alarm_stop":
            if not self.alarm_on:
                return None
            self.alarm_on = False
            return SoundEvent(kind, "reverse_alarm", emitter, sample, c.alarm_db, detail)
        if kind == "gear_change":
            return SoundEvent(kind, "gearshift", emitter, sample, c.gearshift_db, detail, self._draws.next_throw())
        if kind == "ratchet_click":
            return SoundEvent(kind, "ratchet", emitter, sample, c.ratchet_db, detail, self._draws.next_click())
        if kind == "key_turn":
            return SoundEvent(kind, "key_turning", emitter, sample, c.key_db, detail, signal)
        if kind == "voice_call":
            return SoundEvent(kind, "human_voice", emitter, sample, c.voice_db, detail, signal)
        # distractor: the class is in ``detail``
        level = c.horn_db if emitter == "horn" else c.loudspeaker_db
        return SoundEvent(kind, detail, emitter, sample, level, "", signal)
