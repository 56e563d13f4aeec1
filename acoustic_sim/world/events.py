"""Sound events from physics: what the world sounds like, and exactly when.

Physics makes sounds through mechanisms and requests:

==================  =================  ==============================  =======================
event kind          sound class        emitter (source) / anchor site   when
==================  =================  ==============================  =======================
``alarm_start``     ``reverse_alarm``  ``alarm`` / dashboard speaker   gearshift enters R (loops; after ``alarm_delay_s``)
``alarm_stop``      ``reverse_alarm``  ``alarm``                       gearshift leaves R
``gear_change``     ``gearshift``      ``gearshift`` / knob            lever enters another detent
``ratchet_click``   ``ratchet``        ``ratchet`` / brake pawl        the pawl snaps behind a tooth
``key_turn``        ``key_turning``    ``ignition`` / ignition         :meth:`SoundEvents.schedule_key_turn`
``voice_call``      ``human_voice``    ``voice`` / person's mouth      :meth:`SoundEvents.schedule_call`
``distractor``      any class          ``horn`` (cabin) / horn site,   :meth:`SoundEvents.schedule_distractor`
                                       ``loudspeaker`` (room)
==================  =================  ==============================  =======================

Timing. Mechanisms are observed at every 2 ms physics step; a crossing (into a detent's
capture zone, of the ratchet pawl snapping back) is placed by linear interpolation between the two
physics steps around it and rounded to the nearest sample of the project clock, so the
sound starts within a sample of the interpolated moment. Requests are scheduled at a time
(s) on the project clock. Every event carries its start sample (the master clock), its
kind, its sound class and the emitter (the renderer's source name) it plays from.

Sounds. Every emitter draws its sounds with :func:`acoustic_sim.acoustics.sounds.generate`
from its own generator, spawned in a fixed order from the one passed in: the same seed
and the same physics give the same events and the same samples, and one emitter's sounds
do not depend on what the others did. The objects keep their voice: the reverse alarm is
one beeper (drawn once, cut to whole beep periods so it loops seamlessly), and the ratchet
is one ratchet (one pull drawn once and cut into its clicks, which then play in turn, one
per tooth), and the gearshift is one lever (one ``gearshift`` signal cut into its single
throws, the slide into the detent and its clunk, played in turn, one per gear change); all
three are drawn at :meth:`SoundEvents.reset`. The clicks' and throws' levels apply to the
average click or throw. Key turns, calls and distractors are one natural instance each
(each call a fresh draw of the class, speaker included), drawn when they are requested, so
that no control step pays for them, unless the request passes its own signal.

Outside sounds. The renderer's room must contain every source, but the car horn is
outside the cabin. Its emitter is marked ``outside``: the coupling plays it from where the
straight line from the horn site to the head enters the cabin's air volume (just inside the
windscreen) at the horn's level minus the body's transmission loss
(:attr:`EventsConfig.transmission_loss_db`) minus the spreading from the horn to that point
(:meth:`Coupling.through_body <acoustic_sim.world.coupling.Coupling.through_body>`, the one
law for sounds from outside, which scheduled sounds outside the room follow too).
"""

from __future__ import annotations

import collections
import dataclasses
import heapq
import math

import numpy as np
from scipy.ndimage import maximum_filter1d

from acoustic_sim.acoustics import sounds
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE
from acoustic_sim.world import names
from acoustic_sim.world.view import GearshiftGeometry, RatchetGeometry

EVENT_KINDS = ("alarm_start", "alarm_stop", "gear_change", "ratchet_click", "key_turn", "voice_call", "distractor")
"""Every kind of :class:`SoundEvent`."""


@dataclasses.dataclass(frozen=True)
class Emitter:
    """A place in the world that makes sounds: one source in the renderer.

    Attributes
    ----------
    name : str
        Source name in the renderer.
    anchor : str
        Full name of the MuJoCo site it sounds from (it moves with the site's body).
    outside : bool
        The anchor is outside the acoustic room (the car horn): play it through the body.
    """

    name: str
    anchor: str
    outside: bool = False


EMITTERS: dict[str, Emitter] = {
    e.name: e
    for e in (
        Emitter("alarm", names.ALARM_SPEAKER_SITE),
        Emitter("gearshift", names.GEARSHIFT_KNOB_SITE),
        Emitter("ratchet", names.BRAKE_PAWL_SITE),
        Emitter("ignition", names.IGNITION_SITE),
        Emitter("voice", names.PERSON_MOUTH_SITE),
        Emitter("horn", names.HORN_SITE, outside=True),
        Emitter("loudspeaker", names.LOUDSPEAKER_SITE),
    )
}
"""The emitters by name; a scene has those whose anchor site it has."""


@dataclasses.dataclass(frozen=True)
class SoundEvent:
    """One sound event.

    Attributes
    ----------
    kind : str
        One of :data:`EVENT_KINDS`.
    label : str
        The sound class (one of ``sounds.SOUND_CLASSES``): what a classifier should say.
    source : str
        The emitter, i.e. the renderer source it plays from (a key of :data:`EMITTERS`).
    sample : int
        Start (or stop) sample on the project clock.
    level_db : float
        dB SPL at 1 m of the emitted sound (for outside emitters: outside, before the
        body's transmission loss).
    detail : str
        The gear entered (``gear_change``, ``alarm_*``) or the tooth number (``ratchet_click``).
    signal : numpy.ndarray or None
        The unit-RMS mono signal that starts (``None`` for ``alarm_stop``); not compared.
    loop : bool
        The signal repeats until a stop event.
    """

    kind: str
    label: str
    source: str
    sample: int
    level_db: float
    detail: str = ""
    signal: np.ndarray | None = dataclasses.field(default=None, compare=False, repr=False)
    loop: bool = False

    def time_s(self, sample_rate: int = SAMPLE_RATE) -> float:
        """Start time (s) on the project clock."""
        return self.sample / sample_rate

    @property
    def anchor(self) -> str:
        """Full name of the site the sound comes from."""
        return EMITTERS[self.source].anchor


@dataclasses.dataclass(frozen=True, kw_only=True)
class EventsConfig:
    """Levels and timing of the sound events.

    Parameters
    ----------
    alarm_db, gearshift_db, ratchet_db, key_db, voice_db, loudspeaker_db : float
        dB SPL at 1 m (unit-RMS signal) of the reverse-alarm beeper (85), a gear change
        (68), one ratchet click (72), a key turn (62), a called voice (72, raised voice)
        and the room's distractor loudspeaker (75); each -20..160.
    horn_db : float
        dB SPL at 1 m *outside* the car of the horn (108; horns are rated about 105-115).
    transmission_loss_db : float
        Sound reduction (dB, 0-80) of the car body between the horn and the cabin (30:
        closed windows and doors at horn frequencies).
    gearshift_draw_s : float
        Length (s) of the ``gearshift`` signal drawn and cut into single lever throws,
        4-60 (8 s holds about 8 throws).
    click_s : float
        Longest ratchet click (s) cut from the ratchet's pull, 0.005-0.1.
    alarm_draw_s : float
        Length (s) of the beeper signal drawn to find its period, 3-60; the loop holds
        every whole period it contains.
    alarm_delay_s : float
        Latency (s, 0-5) of the reverse alarm's relay and electronics: it starts this long
        after the lever enters R, if the lever is still in R then (0: at once, the paper's).
    prefetch : bool
        Synthesize every requested sound when it is requested, and the mechanisms' signals at
        :meth:`SoundEvents.reset` (no control step pays for synthesis: real-time runs), instead
        of when each is first heard (the default: a reset does not synthesize the calls of a
        30 s episode that ends after 2 s). The signals are the same either way: each emitter's
        generator is drawn in request order.
    """

    alarm_db: float = 85.0
    gearshift_db: float = 68.0
    ratchet_db: float = 72.0
    key_db: float = 62.0
    voice_db: float = 72.0
    loudspeaker_db: float = 75.0
    horn_db: float = 108.0
    transmission_loss_db: float = 30.0
    gearshift_draw_s: float = 8.0
    click_s: float = 0.035
    alarm_draw_s: float = 6.0
    alarm_delay_s: float = 0.0
    prefetch: bool = False

    def __post_init__(self) -> None:
        for f in ("alarm_db", "gearshift_db", "ratchet_db", "key_db", "voice_db", "loudspeaker_db", "horn_db"):
            v = getattr(self, f)
            if not np.isfinite(v) or not -20.0 <= v <= 160.0:
                raise ConfigError(f"EventsConfig.{f} must be -20..160 dB SPL at 1 m, got {v}")
        for f, lo, hi in (("transmission_loss_db", 0.0, 80.0), ("gearshift_draw_s", 4.0, 60.0), ("click_s", 0.005, 0.1),
                          ("alarm_draw_s", 3.0, 60.0), ("alarm_delay_s", 0.0, 5.0)):
            v = getattr(self, f)
            if not np.isfinite(v) or not lo <= v <= hi:
                raise ConfigError(f"EventsConfig.{f} must be {lo}..{hi}, got {v}")


# -- trackers: angle traces -> crossings -------------------------------------------------------------


def _crossing(a: float, b: float, level: float) -> float:
    """Fraction (0, 1] of the segment a -> b at which it reaches ``level``."""
    return (level - a) / (b - a)


class GearshiftTracker:
    """Which detent the lever is in, with hysteresis, from a trace of hinge angles.

    Parameters
    ----------
    geometry : GearshiftGeometry
    angle : float
        The initial hinge angle (rad); the lever starts in the detent whose capture zone
        holds it, or in none.
    """

    def __init__(self, geometry: GearshiftGeometry, angle: float) -> None:
        self.geometry = geometry
        # Plain floats: the tracker runs every control step, on 8 samples.
        d, c, r = (np.asarray(v, dtype=float) for v in (geometry.detents_rad, geometry.capture_rad, geometry.release_rad))
        self._capture_lo, self._capture_hi = (d - c).tolist(), (d + c).tolist()
        self._release_lo, self._release_hi = (d - r).tolist(), (d + r).tolist()
        self.reset(angle)

    def reset(self, angle: float) -> None:
        """Restart at ``angle`` (rad) without events."""
        g = self.geometry.position(angle)
        self.gear: int | None = None if g is None else self.geometry.names.index(g)
        self.last_gear: int | None = self.gear
        self.angle = float(angle)

    def update(self, angles) -> list[tuple[float, str, int]]:
        """Advance over new angle samples; returns ``(position, "enter" | "leave", gear)``.

        ``position`` is the trace position of the crossing: ``j + u`` for a crossing at
        fraction ``u`` (0..1] of the segment from sample ``j - 1`` to ``j`` (sample -1 is
        the last angle of the previous call). Crossings are in time order.
        """
        trace = [float(v) for v in angles]
        if not trace:
            return []
        if not all(map(math.isfinite, trace)):
            raise ConfigError("gearshift angle trace is not finite (did the simulation diverge?)")
        lo, hi = min(self.angle, *trace), max(self.angle, *trace)
        # Fast path (nearly every step): the trace stays in the current detent's release zone,
        # or, between detents, touches no capture zone.
        if self.gear is not None:
            if self._release_lo[self.gear] <= lo and hi <= self._release_hi[self.gear]:
                self.angle = trace[-1]
                return []
        elif not any(c0 <= hi and c1 >= lo for c0, c1 in zip(self._capture_lo, self._capture_hi)):
            self.angle = trace[-1]
            return []
        out: list[tuple[float, str, int]] = []
        a = self.angle
        for j, b in enumerate(trace):
            u0 = 0.0  # the segment a -> b, from fraction u0 on
            while True:
                start = a + u0 * (b - a)
                if self.gear is not None:
                    r0, r1 = self._release_lo[self.gear], self._release_hi[self.gear]
                    if r0 <= b <= r1:
                        break
                    u = _crossing(a, b, r1 if b > r1 else r0)
                    out.append((j + u, "leave", self.gear))
                    self.gear, u0 = None, u
                    continue
                # Not in a detent: the first capture edge reached in the direction of motion.
                if b == start:
                    break
                if b > start:
                    hits = [g for g, e in enumerate(self._capture_lo) if start < e <= b]
                    g = hits[0] if hits else None
                    edge = self._capture_lo[g] if hits else 0.0
                else:
                    hits = [g for g, e in enumerate(self._capture_hi) if b <= e < start]
                    g = hits[-1] if hits else None
                    edge = self._capture_hi[g] if hits else 0.0
                if g is None:
                    break
                u = max(_crossing(a, b, edge), u0)
                out.append((j + u, "enter", g))
                self.gear, u0 = g, u
            a = b
        self.angle = a
        return out


class RatchetTracker:
    """Ratchet clicks from traces of the brake lever's and the pawl's angles.

    A click is the pawl snapping back after a pin has lifted it: the pawl angle falls
    through ``pawl_drop_rad`` after having risen above ``pawl_lift_rad``. It counts when
    the lever has reached a tooth that has not clicked yet (so a pawl bouncing on its stop
    does not click twice); a tooth clicks again once the lever has gone back below it
    (which takes the release button). Pulling with the button held passes teeth silently;
    letting the button go then drops the pawl behind the highest one: one click.

    Parameters
    ----------
    geometry : RatchetGeometry
    lever : float
        The initial lever angle (rad); teeth already passed do not click.
    pawl : float
        The initial pawl angle (rad).
    """

    def __init__(self, geometry: RatchetGeometry, lever: float, pawl: float) -> None:
        self.geometry = geometry
        self.reset(lever, pawl)

    def reset(self, lever: float, pawl: float) -> None:
        """Restart at these angles (rad) without events."""
        self.clicked = self.geometry.teeth_engaged(lever)  # teeth 1..clicked have clicked
        self.lifted = pawl > self.geometry.pawl_lift_rad
        self.pawl = float(pawl)

    def update(self, levers, pawls) -> list[tuple[float, int]]:
        """Advance over new angle samples (rad); returns ``(position, tooth)`` per click.

        ``position`` as in :meth:`GearshiftTracker.update`; teeth are 1-based.
        """
        g = self.geometry
        out: list[tuple[float, int]] = []
        levers = [float(v) for v in levers]
        pawls = [float(v) for v in pawls]
        if len(levers) != len(pawls):
            raise ConfigError(f"ratchet traces differ in length: {len(levers)} lever and {len(pawls)} pawl angles")
        if not levers:
            return out
        if not (all(map(math.isfinite, levers)) and all(map(math.isfinite, pawls))):
            raise ConfigError("brake or pawl angle trace is not finite (did the simulation diverge?)")
        lever_min, pawl_max = min(levers), max(pawls)
        if not self.lifted and pawl_max <= g.pawl_lift_rad:
            # Fast path: the pawl stays down, so nothing clicks; teeth the lever went below re-arm.
            self.clicked = min(self.clicked, g.teeth_engaged(lever_min))
            self.pawl = pawls[-1]
            return out
        a = self.pawl
        for j, (lever, b) in enumerate(zip(levers, pawls)):
            engaged = g.teeth_engaged(lever)
            self.clicked = min(self.clicked, engaged)
            if b > g.pawl_lift_rad:
                self.lifted = True
            elif self.lifted and b < g.pawl_drop_rad:
                self.lifted = False
                if engaged > self.clicked:
                    self.clicked = engaged
                    out.append((j + _crossing(a, b, g.pawl_drop_rad) if a > g.pawl_drop_rad else j + 1.0, engaged))
            a = b
        self.pawl = a
        return out


# -- sound material ----------------------------------------------------------------------------------


def onsets(x: np.ndarray, sample_rate: int, *, threshold: float, min_gap_s: float, smooth_s: float = 0.002) -> np.ndarray:
    """Sample indices where the envelope of ``x`` rises through ``threshold`` times its peak.

    The envelope is the running maximum of ``|x|`` over ``smooth_s``; rises closer than
    ``min_gap_s`` to the previous onset are ignored.
    """
    env = maximum_filter1d(np.abs(x), size=max(1, round(smooth_s * sample_rate)))
    on = env > threshold * env.max(initial=0.0)
    rises = np.flatnonzero(on[1:] & ~on[:-1]) + 1
    if on.size and on[0]:
        rises = np.r_[0, rises]
    keep: list[int] = []
    for r in rises:
        if not keep or r - keep[-1] >= min_gap_s * sample_rate:
            keep.append(int(r))
    return np.asarray(keep, dtype=np.int64)


def alarm_loop(rng: np.random.Generator, *, seconds: float = 6.0, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """One beeper's sound cut to whole beep periods, so that it loops with its own rhythm.

    The loop starts at the first beep's onset; its length is the whole number of periods
    (estimated from all beep onsets to a fraction of a sample) that the drawn signal holds.
    The cut falls in the silence between beeps, so the wrap cannot click.
    """
    x = sounds.generate("reverse_alarm", rng, seconds=seconds, sample_rate=sample_rate)
    beeps = onsets(x, sample_rate, threshold=0.3, min_gap_s=0.2)
    if beeps.size < 2:
        raise ConfigError(f"reverse alarm: {seconds} s holds {beeps.size} beep(s); draw a longer signal to find its period")
    period = (beeps[-1] - beeps[0]) / (beeps.size - 1)
    start = int(beeps[0])
    length = round((beeps.size - 1) * period)
    loop = x[start : start + length]
    return loop / np.sqrt(np.mean(loop**2))


def ratchet_clicks(rng: np.random.Generator, *, click_s: float = 0.035, sample_rate: int = SAMPLE_RATE) -> list[np.ndarray]:
    """The clicks of one ratchet: one ``ratchet`` pull cut at its click onsets.

    Each click runs from 1 ms before its onset to the next onset or ``click_s``, whichever
    comes first, with a 3 ms fade-out; the clicks keep their relative levels, scaled
    together to a mean power of 1.
    """
    x = sounds.generate("ratchet", rng, sample_rate=sample_rate)
    starts = onsets(x, sample_rate, threshold=0.2, min_gap_s=0.025, smooth_s=0.001)
    pre = round(0.001 * sample_rate)
    fade = round(0.003 * sample_rate)
    clicks = []
    for i, s in enumerate(starts):
        end = min(s + round(click_s * sample_rate), int(starts[i + 1]) - pre if i + 1 < starts.size else x.size)
        c = x[max(s - pre, 0) : end].copy()
        m = min(fade, c.size)
        c[c.size - m :] *= np.cos(0.5 * np.pi * np.arange(1, m + 1) / (m + 1))
        clicks.append(c)
    if not clicks:
        raise ConfigError("ratchet: the drawn pull has no clicks")
    return _unit_mean_power(clicks)


def gearshift_throws(rng: np.random.Generator, *, seconds: float = 8.0, sample_rate: int = SAMPLE_RATE) -> list[np.ndarray]:
    """Single lever throws (slide into a detent and its clunk) of one gearshift.

    One ``gearshift`` signal of ``seconds`` (one lever: the sound bank draws the lever's
    modes once per instance and repeats its throws) is cut at its silent gaps, which the
    model fills with exact zeros; the last throw, which the signal's end may have cut, is
    dropped.
    """
    x = sounds.generate("gearshift", rng, seconds=seconds, sample_rate=sample_rate)
    silent = np.r_[False, x == 0.0, False]
    edges = np.flatnonzero(np.diff(silent.astype(np.int8)))
    gaps = edges.reshape(-1, 2)  # [start, end) of each run of zeros
    gaps = gaps[gaps[:, 1] - gaps[:, 0] >= round(0.05 * sample_rate)]
    throws, start = [], 0
    for g0, g1 in gaps:
        if g0 > start:
            throws.append(x[start:g0].copy())
        start = g1
    if not throws:
        raise ConfigError(f"gearshift: {seconds} s holds no complete lever throw; draw a longer signal")
    return _unit_mean_power(throws)


def _unit_mean_power(parts: list[np.ndarray]) -> list[np.ndarray]:
    """Scale a bank of sounds together so that their mean power (each over its own
    length) is 1: a level then applies to the average sound, and their differences stay."""
    g = 1.0 / np.sqrt(np.mean([np.mean(p**2) for p in parts]))
    return [p * g for p in parts]


# -- the event source ----------------------------------------------------------------------------------


class _Deferred:
    """A requested sound's signal, drawn from its emitter's generator when first needed."""

    __slots__ = ("emitter", "label", "signal")

    def __init__(self, emitter: str, label: str) -> None:
        self.emitter, self.label = emitter, label
        self.signal: np.ndarray | None = None


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
        self._rngs = dict(zip(EMITTERS, rng.spawn(len(EMITTERS))))
        self.gearshift = GearshiftTracker(gearshift, 0.0) if gearshift is not None else None
        self.ratchet = RatchetTracker(ratchet, 0.0, 0.0) if ratchet is not None else None
        if self.gearshift is not None and "R" not in gearshift.names:
            raise ConfigError(f"the gearshift has no reverse gear 'R': gears {gearshift.names}")
        self._alarm_loop: np.ndarray | None = None
        self._clicks: list[np.ndarray] | None = None
        self._n_clicks = 0
        self._throws: list[np.ndarray] | None = None
        self._n_throws = 0
        self._queue: list[tuple[int, int, str, str, str, np.ndarray | _Deferred | None]] = []
        self._deferred: dict[str, collections.deque] = {}
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
                self._beeper()
            if self.ratchet is not None and "ratchet" in self.emitters:
                self._ratchet_clicks()
            if self.gearshift is not None and "gearshift" in self.emitters:
                self._gear_throws()

    # Each mechanism's signal, drawn once from its emitter's own generator (which nothing else
    # draws from), whenever that is: the same signal at reset or at the first event.
    def _beeper(self) -> np.ndarray:
        if self._alarm_loop is None:
            self._alarm_loop = alarm_loop(self._rngs["alarm"], seconds=self.config.alarm_draw_s, sample_rate=self.sample_rate)
        return self._alarm_loop

    def _ratchet_clicks(self) -> list[np.ndarray]:
        if self._clicks is None:
            self._clicks = ratchet_clicks(self._rngs["ratchet"], click_s=self.config.click_s, sample_rate=self.sample_rate)
        return self._clicks

    def _gear_throws(self) -> list[np.ndarray]:
        if self._throws is None:
            self._throws = gearshift_throws(self._rngs["gearshift"], seconds=self.config.gearshift_draw_s,
                                            sample_rate=self.sample_rate)
        return self._throws

    def _later(self, emitter: str, label: str) -> _Deferred:
        """A requested sound's signal, drawn when first needed (at once with ``prefetch``)."""
        d = _Deferred(emitter, label)
        self._deferred.setdefault(emitter, collections.deque()).append(d)
        if self.config.prefetch:
            self._resolve(d)
        return d

    def _resolve(self, d: _Deferred) -> np.ndarray:
        """``d``'s signal: the emitter's earlier requests are drawn first, so each request gets
        the draw it would have had when it was made."""
        queue = self._deferred[d.emitter]
        while d.signal is None:
            first = queue.popleft()
            first.signal = self._draw(first.emitter, first.label)
        return d.signal

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
        x = np.asarray(signal, dtype=float)
        if x.ndim != 1 or x.size == 0 or not np.all(np.isfinite(x)):
            raise ConfigError(f"{what}: signal must be a non-empty finite 1-D array (unit RMS), got shape {x.shape}")
        return x

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
        self._push(s, "voice_call", "voice", "", x if x is not None else self._later("voice", "human_voice"))
        return s

    def schedule_key_turn(self, t: float | None = None, *, signal=None) -> int:
        """The ignition key turns at time ``t`` (s); see :meth:`schedule_call`."""
        self._need_emitter("ignition", "schedule_key_turn")
        s = self._request_sample(t, "schedule_key_turn")
        x = self._signal(signal, "schedule_key_turn")
        self._push(s, "key_turn", "ignition", "", x if x is not None else self._later("ignition", "key_turning"))
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
        self._push(s, "distractor", emitter, label, x if x is not None else self._later(emitter, label))
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
        pending = self._deferred.get(emitter)
        if pending:  # the earlier requests draw first, as when they were made
            self._resolve(pending[-1])
        return self._draw(emitter, label)

    def draw_later(self, emitter: str, label: str):
        """:meth:`draw`, deferred: a zero-argument callable that gives the same signal when
        called (at once with ``prefetch``), which a scheduled sound calls when it starts
        (:meth:`acoustic_sim.world.soundscape.Soundscape.schedule_sound`). Raises as :meth:`draw`."""
        self._check_draw(emitter, label, "draw_later")
        d = self._later(emitter, label)
        return lambda: self._resolve(d)

    def _check_draw(self, emitter: str, label: str, what: str) -> None:
        if emitter not in EMITTERS:
            raise ConfigError(f"{what}: unknown emitter {emitter!r}; valid: {', '.join(EMITTERS)}")
        self._need_emitter(emitter, what)
        if label not in sounds.SOUND_CLASSES:
            raise ConfigError(f"{what}: unknown sound class {label!r}; valid: {', '.join(sounds.SOUND_CLASSES)}")

    def _draw(self, emitter: str, label: str) -> np.ndarray:
        # Requested sounds are drawn when requested (a task's reset), not in a control step.
        return sounds.generate(label, self._rngs[emitter], sample_rate=self.sample_rate)

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
            if isinstance(signal, _Deferred):
                signal = self._resolve(signal)
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
            return SoundEvent(kind, "reverse_alarm", emitter, sample, c.alarm_db, detail, self._beeper(), loop=True)
        if kind == "alarm_stop":
            if not self.alarm_on:
                return None
            self.alarm_on = False
            return SoundEvent(kind, "reverse_alarm", emitter, sample, c.alarm_db, detail)
        if kind == "gear_change":
            throws = self._gear_throws()
            x = throws[self._n_throws % len(throws)]
            self._n_throws += 1
            return SoundEvent(kind, "gearshift", emitter, sample, c.gearshift_db, detail, x)
        if kind == "ratchet_click":
            clicks = self._ratchet_clicks()
            x = clicks[self._n_clicks % len(clicks)]
            self._n_clicks += 1
            return SoundEvent(kind, "ratchet", emitter, sample, c.ratchet_db, detail, x)
        if kind == "key_turn":
            return SoundEvent(kind, "key_turning", emitter, sample, c.key_db, detail, signal)
        if kind == "voice_call":
            return SoundEvent(kind, "human_voice", emitter, sample, c.voice_db, detail, signal)
        # distractor: the class is in ``detail``
        level = c.horn_db if emitter == "horn" else c.loudspeaker_db
        return SoundEvent(kind, detail, emitter, sample, level, "", signal)
