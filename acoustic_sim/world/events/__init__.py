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
throws, the slide into the detent and its clunk, played in turn, one per gear change); each
is drawn once, at its first event (at :meth:`SoundEvents.reset` with ``prefetch``). The clicks' and throws' levels apply to the
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

Modules
-------
emitters
    :class:`Emitter` and :data:`EMITTERS`, :class:`SoundEvent`, :class:`EventsConfig`.
crossings
    The detectors: :class:`GearshiftTracker` (detents) and :class:`RatchetTracker` (teeth).
draws
    Each emitter's generator and when it is drawn (:class:`EmitterDraws`).
schedule
    The event source, :class:`SoundEvents`: requests and traces in, events out.

The mechanisms' signals are cut by :mod:`acoustic_sim.acoustics.sounds.cutting` (:func:`alarm_loop`,
:func:`ratchet_clicks`, :func:`gearshift_throws`, :func:`onsets`), re-exported here for the
imports that knew them in this module.
"""

from __future__ import annotations

from acoustic_sim.acoustics.sounds.cutting import alarm_loop, gearshift_throws, onsets, ratchet_clicks
from acoustic_sim.world.events.crossings import GearshiftTracker, RatchetTracker
from acoustic_sim.world.events.draws import EmitterDraws
from acoustic_sim.world.events.emitters import EMITTERS, EVENT_KINDS, Emitter, EventsConfig, SoundEvent
from acoustic_sim.world.events.schedule import SoundEvents

__all__ = [
    "EMITTERS",
    "EVENT_KINDS",
    "Emitter",
    "EmitterDraws",
    "EventsConfig",
    "GearshiftTracker",
    "RatchetTracker",
    "SoundEvent",
    "SoundEvents",
    "alarm_loop",
    "gearshift_throws",
    "onsets",
    "ratchet_clicks",
]
