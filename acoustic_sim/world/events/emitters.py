"""What sounds in the world: the emitters, the event record, and their levels.

An :class:`Emitter` is a site of the scene that makes sounds (one renderer source); a
:class:`SoundEvent` is one sound it starts (or stops) on the project clock;
:class:`EventsConfig` holds the levels and timing (module docstring of
:mod:`acoustic_sim.world.events` for which mechanism or request makes which event).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE
from acoustic_sim.world import names

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
        :meth:`SoundEvents.reset <acoustic_sim.world.events.SoundEvents.reset>` (no control
        step pays for synthesis: real-time runs), instead of when each is first heard (the
        default: a reset does not synthesize the calls of a 30 s episode that ends after 2 s).
        The signals are the same either way: each emitter's generator is drawn in request
        order.
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
