"""The coupling's emitters: one renderer source each, fed through a ring buffer.

Every emitter (:data:`~acoustic_sim.world.events.EMITTERS`) that has sounded is one
renderer source, created at its first event and removed after it has been silent for the
coupling's ``idle_release_s`` plus the room's reverberation. Its signal is a short ring
buffer, played in a loop, that :meth:`EmitterRing.feed` fills with the emitter's sounds
for exactly the samples of the block about to be rendered: events therefore start (and the
alarm stops) on their own sample, several sounds of one emitter overlap, and adding a sound
never costs a new source (which takes tens of milliseconds to set up). The ring holds
pressure at 1 m in pascal (the source's level is 1 Pa for a unit sample), so each sound
carries its own level.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import P_REF, db_spl_to_pa

RING = 8192
"""Samples in an emitter's ring buffer (more than any control block, 4096 at most)."""

UNIT_LEVEL_DB = float(20.0 * np.log10(1.0 / P_REF))
"""Source level (dB SPL at 1 m) at which a unit sample is 1 Pa at 1 m."""

STOP_FADE_S = 0.005
"""A looping sound fades out over this time (s) from its stop sample (a switched-off beeper)."""


def release_samples(idle_release_s: float, room, sample_rate: int) -> int:
    """Samples a silent emitter's source is kept: ``idle_release_s`` (s) plus the reverberation
    of ``room`` (its longest band's RT60 scaled to a 65 dB decay, plus 50 ms; none without a room)."""
    linger = 0.0 if room is None else float(np.max(room.rt60_bands(), initial=0.0)) * 65.0 / 60.0 + 0.05
    return round((idle_release_s + linger) * sample_rate)


@dataclasses.dataclass
class RingSound:
    """One sound of an emitter: pressure at 1 m (Pa) = gain * signal."""

    signal: np.ndarray
    start: int
    gain: float
    loop: bool
    fade: int  # samples of the fade-out after a loop's stop
    stop: int | None = None

    def end(self) -> float:
        """First sample after the sound (inf while a loop runs)."""
        if self.loop:
            return np.inf if self.stop is None else self.stop + self.fade
        return self.start + self.signal.size

    def write(self, out: np.ndarray, b0: int) -> None:
        """Add the sound's samples for ``b0 .. b0 + out.size`` into ``out``."""
        t = np.arange(b0, b0 + out.size)
        idx = t - self.start
        valid = idx >= 0
        if self.loop:
            x = self.signal[np.mod(idx, self.signal.size)]
            if self.stop is not None:
                fade = np.clip(1.0 - (t - self.stop) / self.fade, 0.0, 1.0)
                x = x * (0.5 - 0.5 * np.cos(np.pi * fade))
        else:
            valid &= idx < self.signal.size
            x = self.signal[np.clip(idx, 0, self.signal.size - 1)]
        out += np.where(valid, x, 0.0) * self.gain


@dataclasses.dataclass
class EmitterRing:
    """An emitter's sounds and its renderer source (see the module docstring)."""

    name: str
    anchor: str
    outside: bool
    sounds: list = dataclasses.field(default_factory=list)
    ring: np.ndarray | None = None  # the renderer source's signal (None: no source)
    ring_start: int = 0
    position: np.ndarray | None = None  # room frame, as last given to the renderer
    silent_from: float = 0.0  # sample from which the emitter has nothing left to play

    def play(self, signal: np.ndarray, start: int, level_db: float, loop: bool, sample_rate: int) -> None:
        """Add a sound: unit-RMS ``signal`` from sample ``start`` at ``level_db`` (dB SPL at 1 m)."""
        fade = int(np.ceil(STOP_FADE_S * sample_rate))
        self.sounds.append(RingSound(signal, start, float(db_spl_to_pa(level_db)), loop, fade))
        self.silent_from = np.inf

    def silence(self, sample: int) -> None:
        """Drop every sound: the emitter is silent from ``sample`` on."""
        self.sounds.clear()
        self.silent_from = sample

    def stop_loops(self, sample: int) -> None:
        """Stop the running loops at ``sample`` (they fade out over :data:`STOP_FADE_S`)."""
        for s in self.sounds:
            if s.loop and s.stop is None:
                s.stop = sample

    def drop_finished(self, now: int) -> None:
        """Forget the sounds over before sample ``now``."""
        if self.sounds:
            self.sounds = [s for s in self.sounds if s.end() > now]
            if not self.sounds:
                self.silent_from = now

    def follow(self, position: np.ndarray, threshold_m: float, renderer) -> None:
        """Move to ``position`` (m, room frame), in the renderer too when it has the source,
        once it is more than ``threshold_m`` from the last position given."""
        if self.position is None or np.linalg.norm(position - self.position) > threshold_m:
            self.position = position
            if renderer is not None and self.ring is not None:
                renderer.move_source(self.name, position)

    def feed(self, renderer, b0: int, b1: int, release_samples: int) -> None:
        """Fill the ring for the block ``[b0, b1)``; add the renderer source at the first
        sound, remove it ``release_samples`` after the emitter fell silent."""
        live = bool(self.sounds) or b0 < self.silent_from + release_samples
        if self.ring is None and self.sounds:
            self._open(renderer, b0)
        elif self.ring is not None and not live:
            renderer.remove_source(self.name)
            self.ring = None
        if self.ring is None:
            return
        block = np.zeros(b1 - b0)
        for s in self.sounds:
            s.write(block, b0)
        idx = np.mod(np.arange(b0, b1) - self.ring_start, RING)
        self.ring[idx] = block

    def _open(self, renderer, b0: int) -> None:
        self.ring = np.zeros(RING)
        self.ring_start = b0
        src = renderer.add_source(self.name, self.ring, self.position, level_db=UNIT_LEVEL_DB, start=b0, loop=True)
        if src.signal is not self.ring:
            raise ConfigError("the renderer copied an emitter's ring buffer; the coupling needs it to keep the array it is given")
