"""Streaming binaural renderer: sound pressure at both eardrums, block by block.

Each call of :meth:`BinauralRenderer.render_block` renders the next control block (705
or 706 samples on the sample clock of DESIGN.md) of the sound pressure (Pa) at the left
and right eardrums, for the current head pose and source positions. Per source, the
response is the sum of three parts with their own update rates:

- the **direct path** (image 0), every block, and the **reflections** (images 1.. up to
  the room's ``ism_order``), when the head or the source has moved enough (:mod:`.image_paths`);
- the **tail head**: the start of the source's diffuse tail, up to where it no longer
  depends on the source (:mod:`.late_bus`).

They are summed into one spectrum per source, applied by one overlap-save for all sources
and cross-faded when they change (:mod:`.early_stream`). The rest of the tail is the room's:
one late-reverb bus convolves the sum of all sources with it, sharing the early part's FFTs
(:mod:`.late_bus`). Measurements: docs/notes/renderer.md.

Levels: a source of level ``L`` dB SPL at 1 m with a unit-RMS signal produces, in free
field, RMS pressure ``20 uPa * 10**(L/20) / r`` at distance r (before the head's effect).
"""

from __future__ import annotations

import copy

import numpy as np

from acoustic_sim.acoustics.early_stream import HISTORY, EarlyStream, check_history
from acoustic_sim.acoustics.head_pose import rotation_tuple
from acoustic_sim.acoustics.hrtf_tables import BackgroundNoise, hrtf_tables
from acoustic_sim.acoustics.image_paths import PathResponses, ReflectionSchedule
from acoustic_sim.acoustics.late_bus import BUS_START, TAIL_SPLICE, LateBus
from acoustic_sim.acoustics.render_source import EgoNoise, Source, checked_signal
from acoustic_sim.acoustics.room import Room
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, FrameEnds

__all__ = ["BUS_START", "HISTORY", "TAIL_SPLICE", "BinauralRenderer", "EgoNoise", "Source", "crossfade_ramp"]


def crossfade_ramp(n: int) -> np.ndarray:
    """Weight of the new response over a block of ``n`` (>= 1) samples: a raised cosine
    from 0 (exclusive) to 1; shape (n,)."""
    return 0.5 - 0.5 * np.cos(np.pi * (np.arange(n) + 1) / n)


class BinauralRenderer:
    """Render sources in a room to the two eardrums of a moving head.

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        The ears, at ``sample_rate``. What is derived from the HRTF alone is built once and
        shared with other renderers of the same HRTF (:func:`hrtf_tables`).
    room : acoustic_sim.acoustics.room.Room
        The room (or free field); the head and every source must stay inside it.
    rng : numpy.random.Generator
        The only source of randomness (the late tails, the background and ego noise).
    sample_rate : int
        Hz; the project rate 44100 unless a config says otherwise.
    background : bool
        Add the room's diffuse background noise at ``room.background_db_spl``.
    late : bool
        Add the diffuse late tail (off: image sources only).
    ego_noise : EgoNoise, optional
        The robot's own noise, added at the ears.
    max_block : int
        Longest block of :meth:`render_block`, samples (HRIR plus block <= :data:`HISTORY`).
    reflection_taps : int
        HRIR length for reflections, samples, 4 to the HRIR length (direct path: all of it).
    reflection_interval : int
        While anything moves, re-render reflections at least every this many blocks, >= 1.
    reflection_turn_deg : float
        Re-render them at once after a head turn of more than this, deg, 0-180 (0: any turn).
    reflection_move_m : float
        Likewise when the head or the source has moved more than this; m, 0-10.

    Raises
    ------
    ConfigError
        The HRTF's rate differs, its HRIRs are too long, or an option is out of range.
    """

    def __init__(
        self,
        hrtf,
        room: Room,
        *,
        rng: np.random.Generator,
        sample_rate: int = SAMPLE_RATE,
        background: bool = True,
        late: bool = True,
        ego_noise: EgoNoise | None = None,
        max_block: int = 4096,
        reflection_taps: int = 128,
        reflection_interval: int = 4,
        reflection_turn_deg: float = 5.0,
        reflection_move_m: float = 0.05,
    ) -> None:
        if hrtf.sample_rate != sample_rate:
            raise ConfigError(f"HRTF {hrtf.name!r} is at {hrtf.sample_rate} Hz but the renderer runs at {sample_rate} Hz")
        check_history(hrtf, max_block, sample_rate)
        self._schedule = ReflectionSchedule(reflection_interval, reflection_turn_deg, reflection_move_m)
        self.hrtf = hrtf
        self.room = room
        self.rng = rng
        self.sample_rate = sample_rate
        self.late = late and not room.anechoic
        self.ego_noise = ego_noise
        self.max_block = max_block
        s = self._schedule
        self.reflection_interval, self.reflection_turn_deg, self.reflection_move_m = s.interval, s.turn_deg, s.move_m
        self.tables = hrtf_tables(hrtf)
        """The HRTF's derived tables, shared with every renderer of the same HRTF."""
        self._paths = PathResponses(hrtf, self.tables, sample_rate, reflection_taps)
        # The shared tables themselves (read-only), as every renderer of this HRTF holds them.
        self._table, self._short, self._directions = self._paths.table, self._paths.short, self._paths.directions
        self._late_bus = LateBus(room, self.tables, rng, sample_rate)
        self._background = BackgroundNoise(room.background_db_spl, hrtf, rng, sample_rate) if background and room.background_db_spl > 0 else None
        self.head_position = np.asarray(room.listener, float)
        self.head_rotation = np.eye(3)
        self._head = tuple(self.head_position.tolist())
        self._rot = tuple(self.head_rotation.ravel().tolist())
        self._reset_stream()

    def _reset_stream(self) -> None:
        """Empty the streaming state: no sources, clock at zero."""
        self.sample = 0  # the master clock: next sample to render
        self.frame = 0  # control blocks rendered
        self._frame_start = 0  # the current control block's first sample
        self._ends = FrameEnds(self.sample_rate)  # the clock's frame ends
        self._frame_end = self._ends(1)  # the current control block's end
        self.blocks = 0  # render_block calls
        self.sources: dict[str, Source] = {}
        self._early = EarlyStream(self.max_block)
        self._late_bus = self._late_bus.restarted()
        self._ramps: dict = {}

    # Tests inspect these, held by the parts that own them.
    _nfft = property(lambda self: self._early.nfft)  # FFT size of the early overlap-save (0 before any)
    _spectra = property(lambda self: self._early.spectra)  # the applied responses (S, 2, F)
    _bus_filter = property(lambda self: self._late_bus.filter)  # the late bus's filter (2, L) or None
    _bus = property(lambda self: self._late_bus.convolver)  # its FrameConvolver or None

    # -- scene ----------------------------------------------------------------------------
    def set_head_pose(self, position, rotation) -> None:
        """Head centre and orientation for the next block.

        Parameters
        ----------
        position : array_like, shape (3,)
            Head centre in metres, room frame; inside the room.
        rotation : array_like, shape (3, 3)
            Head to room, a proper rotation (a reflection, determinant -1, is refused:
            it would swap the ears); tolerances in :func:`~.head_pose.rotation_tuple`.

        Raises
        ------
        ConfigError
            If ``rotation`` is not a proper rotation or ``position`` is outside the room.
        """
        r, rot = rotation_tuple(rotation)
        p = np.asarray(position, float)
        if p.shape != (3,) or tuple(p.tolist()) != self._head:  # an unchanged position was checked before
            self.head_position = self.room.check_inside(position, what="head position")
            self._head = tuple(self.head_position.tolist())
        self.head_rotation = r
        self._rot = rot

    def add_source(self, name: str, signal, position, *, level_db: float, start: int | None = None, loop: bool = False) -> Source:
        """Add a source; it starts sounding at sample ``start``.

        Parameters
        ----------
        name : str
            Unique among this renderer's sources.
        signal : array_like, shape (n,)
            Mono signal, n >= 1, finite; its RMS scales the level (unit RMS: ``level_db``).
        position : array_like, shape (3,)
            Metres, room frame, inside the room.
        level_db : float
            dB SPL at 1 m of a unit-RMS signal, -20 to 160.
        start : int, optional
            Clock sample at which the signal starts (default: now, :attr:`sample`).
        loop : bool, optional
            Repeat the signal forever (default False: silent after its end).

        Returns
        -------
        Source
            The renderer's record of the source.

        Raises
        ------
        ConfigError
            A duplicate name, a bad signal or level, or a position outside the room.
        """
        if name in self.sources:
            raise ConfigError(f"a source named {name!r} already exists")
        sig = checked_signal(name, signal, level_db)
        pos = self.room.check_inside(position, what=f"source {name!r} position")
        src = Source(name=name, signal=sig, position=pos, level_db=float(level_db), start=self.sample if start is None else int(start), loop=loop)
        src.images = self.room.image_sources(pos)
        if self.late:
            src.tail_head = self._late_bus.source_tail(src.images, self.head_position, self._early.nfft)
        src.row = self._early.add_row()
        self.sources[name] = src
        return src

    def move_source(self, name: str, position) -> None:
        """Move a source; takes effect, cross-faded, in the next block.

        Parameters
        ----------
        name : str
            One of the renderer's sources.
        position : array_like, shape (3,)
            Metres, room frame, inside the room.

        Raises
        ------
        ConfigError
            No such source, or the position is outside the room.
        """
        src = self._get(name)
        src.position = self.room.check_inside(position, what=f"source {name!r} position")

    def remove_source(self, name: str) -> None:
        """Remove a source; its sound stops at once.

        Parameters
        ----------
        name : str
            One of the renderer's sources.

        Raises
        ------
        ConfigError
            No such source.
        """
        src = self.sources.pop(self._get(name).name)
        self._early.remove_row(src.row, self.sources.values())

    def _get(self, name: str) -> Source:
        if name not in self.sources:
            raise ConfigError(f"no source named {name!r}; sources: {sorted(self.sources)}")
        return self.sources[name]

    # -- rendering ------------------------------------------------------------------------
    def render_block(self, n: int | None = None) -> np.ndarray:
        """Render the next block of eardrum pressure. A block that crosses control-block
        boundaries is rendered in pieces that do not (the late bus is partitioned by control
        blocks), with the poses held; a response change is cross-faded over the first piece.

        Parameters
        ----------
        n : int, optional
            Samples, 1 to ``max_block``; default the length of the next control block on
            the project clock (705 or 706 samples at 44.1 kHz).

        Returns
        -------
        numpy.ndarray, shape (2, n), float64
            Pressure at the left and right eardrums, Pa.

        Raises
        ------
        ConfigError
            A bad ``n``, a source or image inside the head, responses too long to stream,
            or ego noise that is not finite (2, n) pressure.
        """
        if n is None:
            n = self._frame_end - self.sample
        if not 0 < n <= self.max_block:
            raise ConfigError(f"block length must be 1..{self.max_block} samples, got {n}")
        pieces = []
        left = n
        while left:
            m = min(left, self._frame_end - self.sample)
            pieces.append(self._render_sources(m) if self.sources or self._late_bus.convolver is not None else np.zeros((2, m)))
            self.sample += m
            left -= m
            if self.sample == self._frame_end:
                self.frame += 1
                self._frame_start, self._frame_end = self._frame_end, self._ends(self.frame + 1)
        out = pieces[0] if len(pieces) == 1 else np.concatenate(pieces, axis=1)
        if self._background is not None:
            out += self._background(n)
        if self.ego_noise is not None:
            ego = np.asarray(self.ego_noise(n, self.rng), float)
            if ego.shape != (2, n) or not np.all(np.isfinite(ego)):
                raise ConfigError(f"ego noise must return finite (2, {n}) pressure, got {ego.shape}")
            out += ego
        self.blocks += 1
        return out

    def render(self, seconds: float) -> np.ndarray:
        """Render audio in control blocks.

        Parameters
        ----------
        seconds : float
            Length, s, >= 0.

        Returns
        -------
        numpy.ndarray, shape (2, round(seconds * sample_rate)), float64
            Pressure at the eardrums, Pa.
        """
        end = self.sample + int(round(seconds * self.sample_rate))
        blocks = []
        while self.sample < end:
            blocks.append(self.render_block(min(self._frame_end - self.sample, end - self.sample)))
        return np.concatenate(blocks, axis=1) if blocks else np.zeros((2, 0))

    def _render_sources(self, n: int) -> np.ndarray:
        """All sources' early responses (overlap-save, cross-faded) plus the late bus for
        the next ``n`` samples, which lie within one control block; (2, n) float64."""
        sources = list(self.sources.values())
        early = self._early
        frame_len = self._frame_end - self._frame_start
        frame_start = self.sample == self._frame_start
        frame_end = self.sample + n == self._frame_end
        early.write(sources, self.sample, n)
        changed = []
        if sources:
            nfft = early.nfft
            pose = (self._head, self._rot, self.head_position, self.head_rotation)
            changed = early.update(sources, self._paths, self._schedule, pose, self.blocks, n)
            if early.nfft != nfft and self._late_bus.convolver is not None:
                self._late_bus.convolver.set_fft_size(early.nfft)
        nfft = early.nfft
        # Overlap-save for all sources at once (plus, for a whole control block, the late
        # bus in the same inverse FFT); cross-faded if any response changed.
        late = self._late_bus.late_spectrum(nfft, frame_len, frame_start, frame_end)
        spec = early.input_spectrum() if sources else None  # (S, F) complex64
        out = early.filter(spec, changed, late, n, self._ramp).astype(np.float64)
        self._late_bus.advance(out, early.recent, spec, self.sample - self._frame_start, frame_len, frame_start, frame_end, nfft)
        return out

    def _ramp(self, n: int) -> np.ndarray:
        if n not in self._ramps:
            self._ramps[n] = np.asarray(crossfade_ramp(n), np.float32)
        return self._ramps[n]

    # -- responses ------------------------------------------------------------------------
    def early_response(self, src: Source) -> tuple[np.ndarray, tuple]:
        """The early response of ``src`` at the current head pose (direct path and reflections).

        Parameters
        ----------
        src : Source
            One of this renderer's sources.

        Returns
        -------
        response : numpy.ndarray, shape (2, L), float64
            Pressure at the ears per unit pressure at 1 m.
        key : tuple
            Changes whenever the response does.
        """
        return self._paths.early_response(src, (self._head, self._rot, self.head_position, self.head_rotation))

    def impulse_response(self, source_position, *, seconds: float | None = None) -> np.ndarray:
        """The binaural room impulse response (early plus late) at the current head pose.

        A unit impulse streamed through a fresh source of a probe renderer that shares this
        renderer's tables and late-reverb bus: exactly what the renderer applies (no noise,
        no microphone).

        Parameters
        ----------
        source_position : array_like, shape (3,)
            Metres, room frame, inside the room and at least 0.15 m from the head.
        seconds : float, optional
            Length, s (> 0); default the longest part of the response plus 64 samples.

        Returns
        -------
        numpy.ndarray, shape (2, n), float64
            Pressure at the ears per unit pressure at 1 m.
        """
        if self.late:
            self._late_bus.ensure(self.head_position, self._early.nfft)
        probe = copy.copy(self)
        probe._background, probe.ego_noise = None, None
        probe._reset_stream()
        src = probe.add_source("impulse", np.array([1.0]), source_position, level_db=float(20 * np.log10(1 / 20e-6)), start=0)
        if seconds is None:
            tail_len = self._late_bus.filter.shape[1] if self.late else 0
            head_len = src.tail_head.shape[1] if src.tail_head is not None else 0
            seconds = (max(tail_len, head_len, probe.early_response(src)[0].shape[1]) + 64) / self.sample_rate
        return probe.render(seconds)
