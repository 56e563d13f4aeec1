"""Streaming binaural renderer: sound pressure at both eardrums, block by block.

Each call of :meth:`BinauralRenderer.render_block` renders the next control block (705
or 706 samples on the sample clock of DESIGN.md) of the sound pressure (Pa) at the left
and right eardrums, for the current head pose and source positions. Per source, the
response is the sum of three parts with their own update rates:

- **direct path** (image 0), every block: the HRIR of the source's direction relative to
  the current head pose, delayed by its distance (fractional delays from a pre-shifted
  HRIR table) and attenuated by 1/r.
- **reflections** (images 1.. up to the room's ``ism_order``), through the first
  ``reflection_taps`` samples of their HRIRs and their walls' band damping. Re-rendered
  when the head has turned more than ``reflection_turn_deg`` or the head or the source has
  moved more than ``reflection_move_m`` since their last update, and otherwise at most
  every ``reflection_interval`` blocks while anything moves; their spectrum is cached in
  between. When the head turns, every reflection's direction turns with it and its delay
  stays; a displacement changes a delay by at most its length. So the defaults (5 deg,
  5 cm, 4 blocks = 64 ms) keep a turning head's reflections within the KEMAR grid's own
  5 deg azimuth spacing of where per-block updates would put them. Interactive
  room-acoustics engines update reflections at such lower rates than the direct sound,
  which carries the localization cues. For a head turning at 120 deg/s in the car cabin
  this re-renders the reflections on a third of the blocks; octave-band levels and ILDs
  per 46 ms frame stay within 0.2 and 0.3 dB RMS of per-block updates, closer than
  per-block updates with the head pose 16 ms late (tested).
- **late tail head**: the start of the source's diffuse tail (:func:`late_tail`), where
  its fill still depends on which images were rendered, up to where the fill is complete.

All three are summed into one spectrum per source and applied by overlap-save with one
FFT size shared by all sources. Whenever any part changes, the block is filtered with the
old and the new response and cross-faded (raised cosine over the block), which is exact
time-varying filtering with the response interpolated across the block: no clicks. The
cross-fade is linear in the sources, so all sources share one inverse FFT of both.

The rest of the tail, after every source's fill is complete, is the room's and not the
source's (the statistical late energy at time t after emission does not depend on where
the source is): one **late-reverb bus** per renderer convolves the sum of all sources'
signals with it (:class:`FrameConvolver`), from :data:`BUS_START` samples on. Its
partitions are the control blocks themselves, so it reuses the early overlap-save's input
FFT and adds its spectrum before the early inverse FFT: the cabin's 0.34 s tail costs
one multiply-add per partition and bin, no FFT of its own. That takes a fifth less time
than a separate uniformly partitioned convolver with 1024-sample partitions, itself the
fastest of the uniform and non-uniform partitionings tried here (small FFTs, not the
multiply-adds, dominate at these sizes). Each source's tail head ends with a short
power-complementary cross-fade into the bus and subtracts the bus's own response before
that point, so the tail that each source gets is exactly its own head followed by the
room's tail.

Arithmetic is float32/complex64 (its rounding is 130 dB below the signal, measured
against float64: under the microphone's self-noise up to its overload point), in
preallocated buffers, with a handful of numpy calls per block.

Levels: a source of level ``L`` dB SPL at 1 m with a unit-RMS signal produces, in free
field, RMS pressure ``20 uPa * 10**(L/20) / r`` at distance r (before the head's effect).
"""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Protocol

import numpy as np
import scipy.fft as sfft

from acoustic_sim.acoustics.convolution import FrameConvolver, assemble, irfft, rfft
from acoustic_sim.acoustics.hrtf_tables import FRACTIONAL_PHASES, BackgroundNoise, hrtf_tables
from acoustic_sim.acoustics.room import ImageSources, Room, late_tail, tail_complete_sample
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE, P_REF, SAMPLE_RATE, SPEED_OF_SOUND, db_spl_to_pa, frame_end_sample

HISTORY = 1 << 14
"""Input samples kept per source for the early response (longer responses are refused)."""

BUS_START = 1024
"""Where the late-reverb bus starts (samples into the response): before any source's tail
fill completes in small rooms (the car cabin: 25-28 ms), and after a control block (the
bus's partitions are control blocks; a higher sample rate starts it after its longest)."""

TAIL_SPLICE = 64
"""Length (samples) of the cross-fade from a source's own tail head into the bus."""


def crossfade_ramp(n: int) -> np.ndarray:
    """Weight (n,) of the new response over a block: a raised cosine from 0 to 1."""
    return 0.5 - 0.5 * np.cos(np.pi * (np.arange(n) + 1) / n)


def _fft_size(n: int) -> int:
    """Smallest FFT length >= n of the form 2**k or 3 * 2**k (both fast in pocketfft)."""
    p2 = 1 << max(int(n - 1).bit_length(), 0)
    p3 = 3 * (1 << max(int(-(-n // 3) - 1).bit_length(), 0))
    return min(p2, p3)


class EgoNoise(Protocol):
    """The robot's own noise at the ears (motors, gears): the world drives it later.

    ``__call__(n, rng)`` returns the next ``n`` samples of pressure (Pa) at both ears,
    shape (2, n).
    """

    def __call__(self, n: int, rng: np.random.Generator) -> np.ndarray: ...


@dataclasses.dataclass(eq=False)
class Source:
    """A sound source in the room (positions in metres, room frame).

    Attributes
    ----------
    name : str
    signal : numpy.ndarray, shape (n,)
        Mono signal, scaled so that its RMS is the source's level (see ``level_db``).
    position : numpy.ndarray, shape (3,)
    level_db : float
        dB SPL at 1 m of a unit-RMS ``signal`` (free field, on axis).
    start : int
        Sample (project clock) at which the signal starts; silence before.
    loop : bool
        Repeat the signal forever instead of falling silent at its end.
    """

    name: str
    signal: np.ndarray
    position: np.ndarray
    level_db: float
    start: int = 0
    loop: bool = False
    # renderer state
    images: ImageSources | None = None
    row: int = 0  # the source's row in the renderer's input and spectrum buffers
    direct_key: tuple | None = None  # (HRIR index, whole delay, phase, distance) of the direct path
    direct: np.ndarray | None = None  # its spectrum (2, F) at the renderer's FFT size
    reflections: tuple | None = None  # geometry (idx, whole, phase, weights, key) of the last reflection update
    reflection_pose: tuple | None = None  # (head position, head rotation, source position, block) of that update
    reflected: np.ndarray | None = None  # spectrum (2, F) of the reflections plus the tail head
    band_factors: tuple | None = None  # SVD of the reflections' band damping
    placement: tuple | None = None  # reflections' position-only geometry for (head, source) positions (a cache)
    tail_head: np.ndarray | None = None  # (2, T): own tail up to the bus, minus the bus there
    tail_spectrum: np.ndarray | None = None  # its rFFT at the renderer's FFT size (a cache)
    fresh: bool = True  # no block rendered yet: the first response applies without a cross-fade

    def emitted(self, start: int, n: int) -> np.ndarray:
        """Pressure at 1 m (Pa, before spreading) for samples ``start .. start+n`` of the clock."""
        gain = P_REF * 10.0 ** (self.level_db / 20.0)
        sig = self.signal
        i0 = start - self.start
        if self.loop and i0 >= 0:
            i0 %= sig.size
            if i0 + n <= sig.size:
                return sig[i0 : i0 + n] * gain
        elif not self.loop and 0 <= i0 and i0 + n <= sig.size:
            return sig[i0 : i0 + n] * gain
        idx = np.arange(start, start + n) - self.start
        if self.loop:
            valid = idx >= 0
            out = np.where(valid, sig[np.mod(idx, sig.size)], 0.0)
        else:
            valid = (idx >= 0) & (idx < sig.size)
            out = np.where(valid, sig[np.clip(idx, 0, sig.size - 1)], 0.0)
        return out * gain


class BinauralRenderer:
    """Render sources in a room to the two eardrums of a moving head.

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        The ears. Its sample rate must equal ``sample_rate``. What the renderer derives
        from the HRTF alone is built once and shared with other renderers of the same HRTF
        (:func:`hrtf_tables`).
    room : acoustic_sim.acoustics.room.Room
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
        Longest block accepted by :meth:`render_block` (samples).
    reflection_taps : int
        HRIR length (samples) used for reflections; the direct path uses the full HRIR.
    reflection_interval : int
        While the head or a source moves, re-render its reflections at least every this
        many blocks (1 = every block).
    reflection_turn_deg : float
        Re-render the reflections at once when the head has turned more than this (deg)
        since their last update (0 = at every change).
    reflection_move_m : float
        Likewise when the head or the source has moved more than this (m).
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
        if _fft_size(hrtf.n_taps + max_block) > HISTORY:  # would fail at the first block
            raise ConfigError(
                f"HRTF {hrtf.name!r} has HRIRs of {hrtf.n_taps} samples ({1e3 * hrtf.n_taps / sample_rate:.0f} ms); "
                f"with blocks of up to {max_block} samples the renderer streams responses (HRIR plus "
                f"propagation delay) of at most {HISTORY - max_block} samples: use shorter HRIRs or a smaller max_block"
            )
        if not isinstance(reflection_interval, (int, np.integer)) or reflection_interval < 1:
            raise ConfigError(f"reflection_interval must be an integer >= 1 (blocks), got {reflection_interval!r}")
        if not 0.0 <= reflection_turn_deg <= 180.0:
            raise ConfigError(f"reflection_turn_deg must be 0..180 deg, got {reflection_turn_deg}")
        if not 0.0 <= reflection_move_m <= 10.0:
            raise ConfigError(f"reflection_move_m must be 0..10 m, got {reflection_move_m}")
        self.hrtf = hrtf
        self.room = room
        self.rng = rng
        self.sample_rate = sample_rate
        self.late = late and not room.anechoic
        self.ego_noise = ego_noise
        self.max_block = max_block
        self.reflection_interval = int(reflection_interval)
        self.reflection_turn_deg = float(reflection_turn_deg)
        self.reflection_move_m = float(reflection_move_m)
        self._turn_cos = math.cos(math.radians(self.reflection_turn_deg))
        self.tables = hrtf_tables(hrtf)
        """The HRTF's derived tables, shared with every renderer of the same HRTF."""
        self._table = self.tables.hrir
        self._taps = self.tables.taps
        short = min(reflection_taps, hrtf.hrir.shape[-1])
        self._short = self.tables.short_hrir(short)
        self._short_taps = short + 1
        self._directions = self.tables.directions
        self._band_weights: dict = {}
        self._bus_filter = None  # (2, L) the room's late tail after _bus_start, shared by all sources
        longest_block = math.ceil(sample_rate / FRAME_RATE)
        self._bus_start = max(BUS_START, 1 << (longest_block - 1).bit_length())
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
        self._frame_end = int(frame_end_sample(1, self.sample_rate))  # and its end
        self._ends = (0, [])  # frame ends from a first frame on, fetched in batches
        self.blocks = 0  # render_block calls
        self.sources: dict[str, Source] = {}
        self._nfft = 0  # FFT size of the early overlap-save, shared by all sources
        self._inputs = np.zeros((0, 2 * HISTORY + 4 * self.max_block), np.float32)  # per-source input history
        self._pos = HISTORY  # write position in _inputs (HISTORY samples of past before it)
        self._spectra = np.zeros((0, 2, 1), np.complex64)  # applied response spectra (S, 2, F)
        self._bus = FrameConvolver(self._bus_filter) if self._bus_filter is not None else None
        self._bus_block = None  # the bus's output for the current control block, when rendered in pieces
        self._ramps: dict = {}
        self._scratch: dict = {}

    # -- scene ----------------------------------------------------------------------------
    def set_head_pose(self, position, rotation) -> None:
        """Head centre and orientation for the next block.

        Parameters
        ----------
        position : array_like, shape (3,)
            Head centre in metres, room frame; inside the room.
        rotation : array_like, shape (3, 3)
            Head to room, a proper rotation: orthonormal (each row's squared norm within
            1.1e-5 of 1, rows orthogonal within 1e-6) with determinant +1. A reflection
            (determinant -1, e.g. ``diag(1, -1, 1)``) is refused: it would render a
            mirrored world, left and right ears swapped.

        Raises
        ------
        ConfigError
            If ``rotation`` is not a proper rotation or ``position`` is outside the room.
        """
        r = np.asarray(rotation, float)
        rot = tuple(r.ravel().tolist()) if r.shape == (3, 3) else (np.nan,) * 9
        # R R^T = I within numpy.allclose(atol=1e-6) tolerances, in scalar arithmetic:
        # this runs every control step (NaN fails every comparison). Orthonormal rows
        # make the determinant +-1 within ~2e-5, so its sign tells rotation from reflection.
        a, b, c, d, e, f, g, h, i = rot
        if not (
            abs(a * a + b * b + c * c - 1.0) <= 1.1e-5
            and abs(d * d + e * e + f * f - 1.0) <= 1.1e-5
            and abs(g * g + h * h + i * i - 1.0) <= 1.1e-5
            and abs(a * d + b * e + c * f) <= 1e-6
            and abs(a * g + b * h + c * i) <= 1e-6
            and abs(d * g + e * h + f * i) <= 1e-6
        ):
            raise ConfigError(f"head rotation must be a 3x3 rotation matrix, got {r.tolist()}")
        if a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) <= 0.0:
            raise ConfigError(f"head rotation must be a proper rotation (determinant +1), got a reflection {r.tolist()}")
        p = np.asarray(position, float)
        if p.shape != (3,) or tuple(p.tolist()) != self._head:  # an unchanged position was checked before
            self.head_position = self.room.check_inside(position, what="head position")
            self._head = tuple(self.head_position.tolist())
        self.head_rotation = r
        self._rot = rot

    def add_source(self, name: str, signal, position, *, level_db: float, start: int | None = None, loop: bool = False) -> Source:
        """Add a source; it starts sounding at sample ``start`` (default: now)."""
        if name in self.sources:
            raise ConfigError(f"a source named {name!r} already exists")
        sig = np.asarray(signal, dtype=float)
        if sig.ndim != 1 or sig.size == 0 or not np.all(np.isfinite(sig)):
            raise ConfigError(f"source {name!r}: signal must be a non-empty finite 1-D array, got shape {sig.shape}")
        if not np.isfinite(level_db) or not -20 <= level_db <= 160:
            raise ConfigError(f"source {name!r}: level_db must be -20..160 dB SPL at 1 m, got {level_db}")
        pos = self.room.check_inside(position, what=f"source {name!r} position")
        src = Source(name=name, signal=sig, position=pos, level_db=float(level_db), start=self.sample if start is None else int(start), loop=loop)
        src.images = self.room.image_sources(pos)
        if self.late:
            src.tail_head = self._tail_head(src)
        src.row = len(self.sources)
        self._inputs = np.concatenate([self._inputs, np.zeros((1, self._inputs.shape[1]), np.float32)])
        self._spectra = np.concatenate([self._spectra, np.zeros((1,) + self._spectra.shape[1:], np.complex64)])
        self.sources[name] = src
        return src

    def move_source(self, name: str, position) -> None:
        """Move a source (m, room frame); takes effect, cross-faded, in the next block."""
        src = self._get(name)
        src.position = self.room.check_inside(position, what=f"source {name!r} position")

    def remove_source(self, name: str) -> None:
        src = self.sources.pop(self._get(name).name)
        keep = np.arange(self._inputs.shape[0]) != src.row
        self._inputs, self._spectra = self._inputs[keep], self._spectra[keep]
        for i, other in enumerate(self.sources.values()):
            other.row = i

    def _get(self, name: str) -> Source:
        if name not in self.sources:
            raise ConfigError(f"no source named {name!r}; sources: {sorted(self.sources)}")
        return self.sources[name]

    # -- rendering ------------------------------------------------------------------------
    def render_block(self, n: int | None = None) -> np.ndarray:
        """Render the next block of eardrum pressure (Pa), shape (2, n).

        ``n`` defaults to the length of the next control block on the project clock (705
        or 706 samples at 44.1 kHz). A block that crosses control-block boundaries is
        rendered in pieces that do not (the late bus is partitioned by control blocks),
        with the poses held; a response change is cross-faded over the first piece.
        """
        if n is None:
            n = self._frame_end - self.sample
        if not 0 < n <= self.max_block:
            raise ConfigError(f"block length must be 1..{self.max_block} samples, got {n}")
        pieces = []
        left = n
        while left:
            m = min(left, self._frame_end - self.sample)
            pieces.append(self._render_sources(m) if self.sources or self._bus is not None else np.zeros((2, m)))
            self.sample += m
            left -= m
            if self.sample == self._frame_end:
                self.frame += 1
                self._frame_start, self._frame_end = self._frame_end, self._end_of_frame(self.frame + 1)
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

    def _end_of_frame(self, k: int) -> int:
        """:func:`frame_end_sample` of frame ``k``, computed 1024 frames at a time."""
        first, ends = self._ends
        if not first <= k < first + len(ends):
            first, ends = self._ends = (k, frame_end_sample(np.arange(k, k + 1024), self.sample_rate).tolist())
        return ends[k - first]

    def render(self, seconds: float) -> np.ndarray:
        """Render ``seconds`` of audio in control blocks; (2, n) Pa."""
        end = self.sample + int(round(seconds * self.sample_rate))
        blocks = []
        while self.sample < end:
            blocks.append(self.render_block(min(self._frame_end - self.sample, end - self.sample)))
        return np.concatenate(blocks, axis=1) if blocks else np.zeros((2, 0))

    def _render_sources(self, n: int) -> np.ndarray:
        """All sources' early responses (overlap-save, cross-faded) plus the late bus for
        the next ``n`` samples, which lie within one control block; (2, n) float64."""
        sources = list(self.sources.values())
        frame_len = self._frame_end - self._frame_start
        frame_start = self.sample == self._frame_start
        frame_end = self.sample + n == self._frame_end
        # 1. Input history: every source's new samples, one row per source.
        pos = self._pos
        if pos + n > self._inputs.shape[1]:
            self._inputs[:, :HISTORY] = self._inputs[:, pos - HISTORY : pos]
            pos = HISTORY
        for src in sources:
            self._inputs[src.row, pos : pos + n] = src.emitted(self.sample, n)
        self._pos = pos = pos + n
        # 2. Responses: direct path every block, reflections when due; the FFT size is
        #    shared and grows (never shrinks) when a longer response appears.
        changed = []
        if sources:
            geometry = [self._direct_geometry(src) for src in sources]
            due = [self._reflections_due(src) for src in sources]
            reflections = [self._reflection_geometry(src) if d else src.reflections for src, d in zip(sources, due)]
            length = max(max(g[-1], r[-1], s.tail_head.shape[1] if s.tail_head is not None else 0) for g, r, s in zip(geometry, reflections, sources))
            nfft = max(self._nfft, _fft_size(length + n - 1))
            if nfft > HISTORY:
                raise ConfigError(
                    f"the sources' early responses are {length} samples long, more than the renderer streams "
                    f"({HISTORY - n}); lower the room's ism_order"
                )
            if nfft != self._nfft:
                self._grow(nfft)
            for src, g, r, d in zip(sources, geometry, reflections, due):
                new = self._update_response(src, g, r, d)
                if new is not None:
                    changed.append((src, new))
        nfft = self._nfft
        # 3. Overlap-save for all sources at once (plus, for a whole control block, the late
        #    bus in the same inverse FFT); cross-fade if any response changed.
        bus = self._bus if nfft else None
        late = bus.output(frame_len) if bus is not None and frame_start else None
        if late is not None and not frame_end:  # a piece of a control block: the bus's block on its own
            self._bus_block = irfft(late, nfft)[:, nfft - frame_len :]
            late = None
        if sources:
            spec = rfft(self._inputs[:, pos - nfft : pos])  # (S, F) complex64
            held = self._spectra
            y_old = spec[0] * held[0] if len(sources) == 1 else (spec[:, None, :] * held).sum(axis=0)
            if late is not None:
                y_old += late
        else:
            spec, y_old = None, late
        if y_old is None:
            y = np.zeros((2, n), np.float32)
        elif not changed:
            y = irfft(y_old, nfft)[:, nfft - n :]
        else:
            # Old response over the whole block plus the ramped change: one inverse FFT of both.
            both = np.empty((2,) + y_old.shape, np.complex64)
            both[0] = y_old
            src, new = changed[0]
            np.multiply(spec[src.row], new - held[src.row], out=both[1])
            held[src.row] = new
            for src, new in changed[1:]:
                both[1] += spec[src.row] * (new - held[src.row])
                held[src.row] = new
            y = irfft(both, nfft)[:, :, nfft - n :]
            y = y[0] + self._ramp(n) * y[1]
        out = y.astype(np.float64)
        # 4. The late bus: its own block if this is a piece of one; feed it the sum of all
        #    sources, and the spectrum of the window that ends with the control block.
        if bus is not None:
            if not (frame_start and frame_end) and self._bus_block is not None:
                offset = self.sample - self._frame_start
                out += self._bus_block[:, offset : offset + n]
            single = len(sources) == 1
            bus.feed(self._inputs[0, pos - n : pos] if single else self._inputs[:, pos - n : pos].sum(axis=0))
            if frame_end:
                if spec is None:
                    spec = np.zeros((1, nfft // 2 + 1), np.complex64)
                bus.push(spec[0] if single else spec.sum(axis=0), frame_len)
                self._bus_block = None
        return out

    def _ramp(self, n: int) -> np.ndarray:
        if n not in self._ramps:
            self._ramps[n] = np.asarray(crossfade_ramp(n), np.float32)
        return self._ramps[n]

    def _grow(self, nfft: int) -> None:
        """Move every held spectrum to a new FFT size (the same responses, zero-padded)."""
        if self._nfft:
            self._spectra = sfft.rfft(sfft.irfft(self._spectra, n=self._nfft, axis=-1), n=nfft, axis=-1).astype(np.complex64)
        else:
            self._spectra = np.zeros((self._spectra.shape[0], 2, nfft // 2 + 1), np.complex64)
        self._nfft = nfft
        if self._bus is not None:
            self._bus.set_fft_size(nfft)
        for src in self.sources.values():
            src.direct_key, src.direct, src.reflected = None, None, None

    def _update_response(self, src: Source, direct: tuple, reflections: tuple, due: bool) -> np.ndarray | None:
        """Bring the source's direct and reflection spectra up to date; returns its new
        response spectrum (2, F) if it changed, else None (a new source's first response
        is applied at once, without a cross-fade)."""
        nfft = self._nfft
        changed = False
        if direct[0] != src.direct_key:
            src.direct = self._direct_spectrum(direct[0], nfft)
            src.direct_key = direct[0]
            changed = True
        if due:
            src.reflection_pose = (self._head, self._rot, tuple(src.position.tolist()), self.blocks)
        if src.reflected is None or reflections[-2] != src.reflections[-2]:
            src.reflected = self._reflection_spectrum(src, reflections, nfft)
            src.reflections = reflections
            changed = True
        if not changed:
            return None
        new = src.direct + src.reflected
        if src.fresh:
            self._spectra[src.row] = new
            src.fresh = False
            return None
        return new

    # -- geometry -------------------------------------------------------------------------
    def _direct_geometry(self, src: Source) -> tuple:
        """The direct path for the current pose: (key, length), key = (HRIR index, whole
        delay, fractional phase, distance). Scalar arithmetic: it runs every block."""
        hx, hy, hz = self._head
        sx, sy, sz = src.position.tolist()
        rx, ry, rz = sx - hx, sy - hy, sz - hz
        dist = math.sqrt(rx * rx + ry * ry + rz * rz)
        if dist < 0.15:
            raise ConfigError(f"source {src.name!r} is {dist:.3f} m from the head centre: closer than 0.15 m is inside the head")
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._rot
        # head frame = rel @ R (R maps head to room)
        vx, vy, vz = (rx * r00 + ry * r10 + rz * r20) / dist, (rx * r01 + ry * r11 + rz * r21) / dist, (rx * r02 + ry * r12 + rz * r22) / dist
        idx = self._directions.lookup_one(vx, vy, vz)
        delay = max(dist / SPEED_OF_SOUND * self.sample_rate - self.hrtf.onset_samples, 0.0)
        whole = math.floor(delay)
        phase = round((delay - whole) * FRACTIONAL_PHASES)
        whole += phase // FRACTIONAL_PHASES
        phase %= FRACTIONAL_PHASES
        return (idx, whole, phase, dist), whole + self._taps

    def _reflections_due(self, src: Source) -> bool:
        """Whether to re-render the reflections this block (see the module docstring)."""
        if src.reflection_pose is None:
            return True
        head, rot, where, block = src.reflection_pose
        now = tuple(src.position.tolist())
        if head == self._head and rot == self._rot and where == now:
            return False
        if self.blocks - block >= self.reflection_interval:
            return True
        if math.dist(head, self._head) > self.reflection_move_m or math.dist(where, now) > self.reflection_move_m:
            return True
        a, b = rot, self._rot  # cos of the rotation angle between the poses: (trace(A^T B) - 1) / 2
        cos = 0.5 * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5] + a[6] * b[6] + a[7] * b[7] + a[8] * b[8] - 1.0)
        return cos < self._turn_cos

    def _reflection_geometry(self, src: Source) -> tuple:
        """Per reflection (images 1..): HRTF direction index, integer delay, fractional
        phase and gain per band-shape weight set, for the current pose; with a key that
        changes whenever the response does, and the response length (samples).

        Everything but the directions depends on positions only and is kept while the
        head and the source stand still (a turning head recomputes the directions alone)."""
        where = (self._head, tuple(src.position.tolist()))
        if src.placement is None or src.placement[0] != where:
            images = src.images.at(src.position)[1:]
            rel = images - self.head_position
            dist = np.sqrt((rel * rel).sum(axis=1))
            if dist.size and dist.min() < 0.15:
                raise ConfigError(f"source {src.name!r} has an image {dist.min():.3f} m from the head centre: closer than 0.15 m is inside the head")
            delay = np.maximum(dist * (self.sample_rate / SPEED_OF_SOUND) - self.hrtf.onset_samples, 0.0)
            whole = np.floor(delay).astype(np.int64)
            phase = np.rint((delay - whole) * FRACTIONAL_PHASES).astype(np.int64)
            whole += phase // FRACTIONAL_PHASES
            phase %= FRACTIONAL_PHASES
            weights = self._band_factors(src)[1] / dist if dist.size else np.zeros((1, 0))
            static = whole.tobytes() + phase.tobytes() + dist.astype(np.float32).tobytes()
            length = int(whole.max()) + self._short_taps if dist.size else 0
            src.placement = (where, rel / dist[:, None], whole, phase, weights, static, length)
        _, unit, whole, phase, weights, static, length = src.placement
        idx = self._directions.lookup(unit @ self.head_rotation) if whole.size else whole
        return idx, whole, phase, weights, idx.tobytes() + static, length

    def _band_factors(self, src: Source) -> tuple:
        """The reflections' per-band damping (B, M-1) factored once per source into a few
        spectral shapes (SVD, 99.9% of the energy): (shapes (B, R) or None, weights (R, M-1))."""
        if src.band_factors is None:
            damping = src.images.damping[:, 1:]
            if damping.shape[0] == 1:
                src.band_factors = (None, damping)
            else:
                u, sv, vt = np.linalg.svd(damping, full_matrices=False)
                rank = int(np.searchsorted(np.cumsum(sv**2) / np.sum(sv**2), 0.999) + 1)
                src.band_factors = (u[:, :rank], sv[:rank, None] * vt[:rank])
        return src.band_factors

    # -- spectra --------------------------------------------------------------------------
    def _scratch_buffer(self, nfft: int) -> np.ndarray:
        if nfft not in self._scratch:
            self._scratch = {nfft: np.zeros((2, nfft), np.float32)}
        return self._scratch[nfft]

    def _direct_spectrum(self, direct: tuple, nfft: int) -> np.ndarray:
        """rFFT (2, F) of the direct path: the full HRIR at its delay, times 1/r."""
        idx, whole, phase, dist = direct
        buf = self._scratch_buffer(nfft)
        taps = self._taps
        buf[:, whole : whole + taps] = self._table[idx, phase].reshape(taps, 2).T
        buf[:, whole : whole + taps] *= np.float32(1.0 / dist)
        spec = rfft(buf)
        buf[:, whole : whole + taps] = 0.0
        return spec

    def _reflection_spectrum(self, src: Source, reflections: tuple, nfft: int) -> np.ndarray:
        """rFFT (2, F) of the reflections plus the source's tail head.

        Images are overlap-added straight onto the FFT grid (:func:`assemble`) through
        the first ``reflection_taps`` samples of their HRIRs (faded out: nearly all of
        the energy and the direction cues, at a quarter of the cost). With frequency-
        dependent walls each band shape's image gains go into their own sum, which is then
        shaped by its band response. Spreading (1/r) scales images, not bands.
        """
        idx, whole, phase, weights, _, _ = reflections
        shapes = self._band_factors(src)[0]
        if idx.size:
            parts_spec = rfft(assemble(self._short[idx, phase], whole, nfft, weights))  # (R, 2, F)
            spec = parts_spec[0] if shapes is None else (self._band_shapes(shapes, nfft)[:, None, :] * parts_spec).sum(axis=0)
        else:
            spec = np.zeros((2, nfft // 2 + 1), np.complex64)
        if src.tail_head is not None:
            if src.tail_spectrum is None or src.tail_spectrum.shape[-1] != nfft // 2 + 1:
                src.tail_spectrum = sfft.rfft(src.tail_head.astype(np.float32), n=nfft, axis=-1)
            spec = spec + src.tail_spectrum
        return spec

    def early_response(self, src: Source) -> tuple[np.ndarray, tuple]:
        """The early binaural response (2, L) of ``src`` for the current head pose (direct
        path and reflections, freshly computed), in the renderer's units (pressure at the
        ear per unit pressure at 1 m), and a key that changes whenever the response does."""
        direct, direct_len = self._direct_geometry(src)
        reflections = self._reflection_geometry(src)
        length = max(direct_len, reflections[-1])
        nfft = _fft_size(length)
        spec = self._direct_spectrum(direct, nfft) + self._reflection_spectrum(dataclasses.replace(src, tail_head=None, tail_spectrum=None), reflections, nfft)
        h = sfft.irfft(spec, n=nfft, axis=-1)[:, :length].astype(np.float64)
        return h, (direct, reflections[-2])

    def _band_shapes(self, values: np.ndarray, nfft: int) -> np.ndarray:
        """Zero-phase gains (R, nfft//2+1) interpolating octave-band values (B, R) on a
        log-frequency axis (constant beyond the first and last band centres)."""
        key = (nfft, values.shape[0], values.tobytes())
        if key not in self._band_weights:
            freqs = np.log2(np.maximum(np.fft.rfftfreq(nfft, 1.0 / self.sample_rate), 1.0))
            centres = np.log2(125.0 * 2.0 ** np.arange(values.shape[0]))
            eye = np.eye(values.shape[0])
            weights = np.stack([np.interp(freqs, centres, e) for e in eye])  # (B, F)
            self._band_weights[key] = (values.T @ weights).astype(np.float32)
        return self._band_weights[key]

    # -- the late tail --------------------------------------------------------------------
    def _diffuse_field(self) -> tuple:
        return self.tables.diffuse_field()

    def _ensure_bus(self) -> np.ndarray:
        """The room's late tail after :data:`BUS_START` (zero before), made once per
        renderer and shared by all its sources (and by :meth:`impulse_response`)."""
        if self._bus_filter is None:
            power, coherence = self._diffuse_field()
            tail = late_tail(self.room, None, self.head_position, diffuse_power=power, coherence=coherence, rng=self.rng, sample_rate=self.sample_rate)
            tail[:, : self._bus_start] = 0.0
            self._bus_filter = tail
            self._bus = FrameConvolver(tail)
            if self._nfft:
                self._bus.set_fft_size(self._nfft)
        return self._bus_filter

    def _tail_head(self, src: Source) -> np.ndarray:
        """The source's own tail (2, T) up to where the bus takes over, minus the bus's
        response there, so that head plus bus is: the source's own tail until its fill is
        complete (and at least until the bus starts), a power-complementary cross-fade of
        :data:`TAIL_SPLICE` samples, then the room's tail on the bus."""
        bus = self._ensure_bus()
        power, coherence = self._diffuse_field()
        complete = tail_complete_sample(self.room, src.images, self.head_position, sample_rate=self.sample_rate)
        splice = max(complete, self._bus_start)
        end = min(splice + TAIL_SPLICE, bus.shape[1])
        own = late_tail(self.room, src.images, self.head_position, diffuse_power=power, coherence=coherence, rng=self.rng, sample_rate=self.sample_rate, n_samples=end)
        own = np.pad(own, ((0, 0), (0, end - own.shape[1])))
        fade = np.ones(end)
        w = np.sin(0.5 * np.pi * (np.arange(end - splice) + 0.5) / TAIL_SPLICE)  # bus fade-in
        fade[splice:] = np.sqrt(1.0 - w**2)
        into_bus = np.zeros(end)
        into_bus[splice:] = w
        return own * fade + bus[:, :end] * (into_bus - 1.0)

    def impulse_response(self, source_position, *, seconds: float | None = None) -> np.ndarray:
        """The binaural room impulse response (2, n) from ``source_position`` to the ears
        at the current head pose, early plus late, in pressure per unit pressure at 1 m.

        Rendered by streaming a unit impulse through a fresh source of a probe renderer
        that shares this renderer's tables and late-reverb bus, so it is exactly what the
        renderer applies (no noise, no microphone)."""
        if self.late:
            self._ensure_bus()
        probe = copy.copy(self)
        probe._background, probe.ego_noise = None, None
        probe._reset_stream()
        src = probe.add_source("impulse", np.array([1.0]), source_position, level_db=float(20 * np.log10(1 / 20e-6)), start=0)
        if seconds is None:
            tail_len = self._bus_filter.shape[1] if self.late else 0
            head_len = src.tail_head.shape[1] if src.tail_head is not None else 0
            seconds = (max(tail_len, head_len, probe.early_response(src)[0].shape[1]) + 64) / self.sample_rate
        return probe.render(seconds)
