"""Streaming binaural renderer: sound pressure at both eardrums, block by block.

Each call of :meth:`BinauralRenderer.render_block` renders the next control block (705
or 706 samples on the sample clock of DESIGN.md) of the sound pressure (Pa) at the left
and right eardrums, for the current head pose and source positions. Per source:

- **early part**: every image source up to the room's ``ism_order`` (the direct path is
  image 0) goes through the HRIR of its direction relative to the *current* head pose,
  delayed by its distance (fractional delays from a pre-shifted HRIR table) and attenuated
  by 1/r and its wall reflections. When the head or the source moves, the block is filtered
  with the old and the new response and cross-faded (raised cosine over the block), which is
  exact time-varying filtering with the response interpolated across the block: no clicks.
- **late part**: the room's diffuse tail (:func:`acoustic_sim.acoustics.room.late_tail`),
  independent of head orientation, streamed through a partitioned convolver.

Levels: a source of level ``L`` dB SPL at 1 m with a unit-RMS signal produces, in free
field, RMS pressure ``20 uPa * 10**(L/20) / r`` at distance r (before the head's effect).
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np
import scipy.fft as sfft

from acoustic_sim.acoustics.convolution import PartitionedConvolver, assemble, fractional_hrir_table
from acoustic_sim.acoustics.room import ImageSources, Room, late_tail
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND, db_spl_to_pa, frame_end_sample

HISTORY = 1 << 14
"""Input samples kept per source for the early response (longer responses are refused)."""

FRACTIONAL_PHASES = 8
"""Fractional-delay resolution of image placement (delay error <= 1/16 sample)."""


def crossfade_ramp(n: int) -> np.ndarray:
    """Weight (n,) of the new response over a block: a raised cosine from 0 to 1."""
    return 0.5 - 0.5 * np.cos(np.pi * (np.arange(n) + 1) / n)


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
    history: np.ndarray | None = None
    applied_key: tuple | None = None  # geometry key of the response applied last block
    spectrum: np.ndarray | None = None  # rfft (2, nfft//2+1) of that response
    nfft: int = 0  # FFT size of the source's overlap-save convolution
    early: np.ndarray | None = None  # early spectrum for ``early_key`` at ``early_nfft`` (a cache)
    early_key: tuple | None = None
    early_nfft: int = 0
    band_factors: tuple | None = None  # SVD of the reflections' band damping
    tail: PartitionedConvolver | None = None

    def emitted(self, start: int, n: int) -> np.ndarray:
        """Pressure at 1 m (Pa, before spreading) for samples ``start .. start+n`` of the clock."""
        idx = np.arange(start, start + n) - self.start
        sig = self.signal
        if self.loop:
            valid = idx >= 0
            out = np.where(valid, sig[np.mod(idx, sig.size)], 0.0)
        else:
            valid = (idx >= 0) & (idx < sig.size)
            out = np.where(valid, sig[np.clip(idx, 0, sig.size - 1)], 0.0)
        return out * db_spl_to_pa(self.level_db)


class BinauralRenderer:
    """Render sources in a room to the two eardrums of a moving head.

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        The ears. Its sample rate must equal ``sample_rate``.
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
    ) -> None:
        if hrtf.sample_rate != sample_rate:
            raise ConfigError(f"HRTF {hrtf.name!r} is at {hrtf.sample_rate} Hz but the renderer runs at {sample_rate} Hz")
        self.hrtf = hrtf
        self.room = room
        self.rng = rng
        self.sample_rate = sample_rate
        self.late = late and not room.anechoic
        self.ego_noise = ego_noise
        self.max_block = max_block
        self.sample = 0  # the master clock: next sample to render
        self.frame = 0  # control blocks rendered
        self.head_position = np.asarray(room.listener, float)
        self.head_rotation = np.eye(3)
        self.sources: dict[str, Source] = {}
        self._table = fractional_hrir_table(hrtf.hrir, FRACTIONAL_PHASES)
        self._taps = hrtf.hrir.shape[-1] + 1
        short = min(reflection_taps, hrtf.hrir.shape[-1])
        fade = np.ones(short)
        fade[-short // 4 :] = np.hanning(2 * (short // 4))[short // 4 :]
        self._short = fractional_hrir_table(hrtf.hrir[..., :short] * fade, FRACTIONAL_PHASES)
        self._short_taps = short + 1
        self._directions = DirectionLookup(hrtf)
        self._band_weights: dict = {}
        self._background = BackgroundNoise(room.background_db_spl, hrtf, rng, sample_rate) if background and room.background_db_spl > 0 else None
        self._diffuse = None

    # -- scene ----------------------------------------------------------------------------
    def set_head_pose(self, position, rotation) -> None:
        """Head centre (m, room frame) and orientation (3x3, head to room) for the next block."""
        r = np.asarray(rotation, float)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6):
            raise ConfigError(f"head rotation must be a 3x3 rotation matrix, got {r.tolist()}")
        self.head_position = self.room.check_inside(position, what="head position")
        self.head_rotation = r

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
        src.history = np.zeros(0)
        if self.late:
            src.tail = self._make_tail(src)
        self.sources[name] = src
        return src

    def move_source(self, name: str, position) -> None:
        """Move a source (m, room frame); takes effect, cross-faded, in the next block."""
        src = self._get(name)
        src.position = self.room.check_inside(position, what=f"source {name!r} position")

    def remove_source(self, name: str) -> None:
        self.sources.pop(self._get(name).name)

    def _get(self, name: str) -> Source:
        if name not in self.sources:
            raise ConfigError(f"no source named {name!r}; sources: {sorted(self.sources)}")
        return self.sources[name]

    # -- rendering ------------------------------------------------------------------------
    def render_block(self, n: int | None = None) -> np.ndarray:
        """Render the next block of eardrum pressure (Pa), shape (2, n).

        ``n`` defaults to the length of the next control block on the project clock (705
        or 706 samples at 44.1 kHz).
        """
        if n is None:
            n = int(frame_end_sample(self.frame + 1, self.sample_rate)) - self.sample
        if not 0 < n <= self.max_block:
            raise ConfigError(f"block length must be 1..{self.max_block} samples, got {n}")
        out = np.zeros((2, n))
        for src in self.sources.values():
            out += self._render_source(src, n)
        if self._background is not None:
            out += self._background(n)
        if self.ego_noise is not None:
            ego = np.asarray(self.ego_noise(n, self.rng), float)
            if ego.shape != (2, n) or not np.all(np.isfinite(ego)):
                raise ConfigError(f"ego noise must return finite (2, {n}) pressure, got {ego.shape}")
            out += ego
        self.sample += n
        while self.sample >= frame_end_sample(self.frame + 1, self.sample_rate):
            self.frame += 1
        return out

    def render(self, seconds: float) -> np.ndarray:
        """Render ``seconds`` of audio in control blocks; (2, n) Pa."""
        end = self.sample + int(round(seconds * self.sample_rate))
        blocks = []
        while self.sample < end:
            blocks.append(self.render_block(min(int(frame_end_sample(self.frame + 1, self.sample_rate)) - self.sample, end - self.sample)))
        return np.concatenate(blocks, axis=1) if blocks else np.zeros((2, 0))

    def _render_source(self, src: Source, n: int) -> np.ndarray:
        x = src.emitted(self.sample, n)
        geometry = self._geometry(src)
        key, length = geometry[0], geometry[-1]
        # One FFT size per source, grown (never shrunk) when a longer response appears.
        nfft = max(src.nfft, int(2 ** np.ceil(np.log2(length + n))))
        if nfft > HISTORY:
            raise ConfigError(
                f"source {src.name!r}: its early response is {length} samples long, more than the renderer streams "
                f"({HISTORY - n}); lower the room's ism_order"
            )
        if src.spectrum is not None and nfft != src.nfft:  # re-sample the old response on the new grid
            src.spectrum = sfft.rfft(sfft.irfft(src.spectrum, n=src.nfft, axis=-1), n=nfft, axis=-1)
        src.nfft = nfft
        new = self._early_spectrum(src, geometry, nfft)
        src.history = np.concatenate([src.history, x])[-HISTORY:]
        seg = src.history[-nfft:] if src.history.size >= nfft else np.pad(src.history, (nfft - src.history.size, 0))
        xs = sfft.rfft(seg)
        if src.spectrum is not None and key != src.applied_key:
            # Overlap-save with the old and the new response, cross-faded over the block.
            both = sfft.irfft(xs * np.stack([src.spectrum, new]), n=nfft, axis=-1)[..., -n:]
            ramp = crossfade_ramp(n)
            y = both[0] * (1.0 - ramp) + both[1] * ramp
        else:
            y = sfft.irfft(xs * new, n=nfft, axis=-1)[:, -n:]
        src.spectrum, src.applied_key = new, key
        if src.tail is not None:
            y = y + src.tail.process(x)
        return y

    def _geometry(self, src: Source) -> tuple:
        """Per image: HRTF direction index, integer delay, fractional phase and 1/r, for
        the current head pose; with a key that changes whenever the response does and the
        response length (samples)."""
        images = src.images.at(src.position)
        rel = images - self.head_position
        dist = np.linalg.norm(rel, axis=1)
        if dist.min() < 0.15:
            raise ConfigError(f"source {src.name!r} is {dist.min():.3f} m from the head centre: closer than 0.15 m is inside the head")
        idx = self._directions.lookup((rel @ self.head_rotation) / dist[:, None])
        delay = np.maximum(dist / SPEED_OF_SOUND * self.sample_rate - self.hrtf.onset_samples, 0.0)
        whole = np.floor(delay).astype(np.int64)
        phase = np.rint((delay - whole) * FRACTIONAL_PHASES).astype(np.int64)
        whole += phase // FRACTIONAL_PHASES
        phase %= FRACTIONAL_PHASES
        key = (idx.tobytes(), whole.tobytes(), phase.tobytes(), dist.astype(np.float32).tobytes())
        length = max(int(whole[0]) + self._taps, int(whole[1:].max(initial=0)) + self._short_taps)
        return key, idx, whole, phase, dist, length

    def _early_spectrum(self, src: Source, geometry: tuple, nfft: int) -> np.ndarray:
        """rFFT (2, nfft//2+1) of the early response for ``geometry`` (cached per key).

        Images are overlap-added straight onto the FFT grid (:func:`assemble`): the
        direct path through the full HRIR, reflections through its first
        ``reflection_taps`` samples (faded out: nearly all of its energy and its direction
        cues, at a quarter of the cost). With frequency-dependent walls, the reflections'
        per-band damping (B, M) is factored once per source into a few spectral shapes (SVD,
        99.9% of the energy); each shape's image gains go into their own sum, which is then
        shaped by its band response. Spreading (1/r) scales images, not bands.
        """
        key, idx, whole, phase, dist, length = geometry
        if key == src.early_key and nfft == src.early_nfft:
            return src.early
        damping = src.images.damping
        if damping.shape[0] == 1:
            shapes, weights = None, damping[:, 1:] / dist[1:]
        else:
            if src.band_factors is None:
                u, sv, vt = np.linalg.svd(damping[:, 1:], full_matrices=False)
                rank = int(np.searchsorted(np.cumsum(sv**2) / np.sum(sv**2), 0.999) + 1)
                src.band_factors = (u[:, :rank], sv[:rank, None] * vt[:rank])
            u, factors = src.band_factors
            shapes, weights = self._band_shapes(u, nfft), factors / dist[1:]
        # Reflections: one overlap-add per weight set, straight onto the FFT grid.
        parts = np.zeros((weights.shape[0], 2, nfft))
        if dist.size > 1:
            parts = assemble(self._short[idx[1:], phase[1:]], whole[1:], nfft, weights)
        # The direct path goes to its own (unshaped) part when the walls shape the others.
        direct = self._table[idx[0], phase[0]].reshape(-1, 2).T / dist[0]
        if shapes is not None:
            parts = np.concatenate([np.zeros((1, 2, nfft)), parts])
        parts[0, :, whole[0] : whole[0] + direct.shape[1]] += direct
        spec_parts = sfft.rfft(parts, axis=-1)  # (parts, 2, F)
        spec = spec_parts[0]
        if shapes is not None:
            spec = spec + (spec_parts[1:] * shapes[:, None, :]).sum(axis=0)
        src.early, src.early_key, src.early_nfft = spec, key, nfft
        return spec

    def early_response(self, src: Source) -> tuple[np.ndarray, tuple]:
        """The early binaural response (2, L) of ``src`` for the current head pose, in
        the renderer's units (pressure at the ear per unit pressure at 1 m), and a key that
        changes whenever the response does."""
        geometry = self._geometry(src)
        key, length = geometry[0], geometry[-1]
        nfft = max(src.nfft, int(2 ** np.ceil(np.log2(length))))
        h = sfft.irfft(self._early_spectrum(src, geometry, nfft), n=nfft, axis=-1)[:, :length]
        return h, key

    def _band_shapes(self, values: np.ndarray, nfft: int) -> np.ndarray:
        """Zero-phase gains (R, nfft//2+1) interpolating octave-band values (B, R) on a
        log-frequency axis (constant beyond the first and last band centres)."""
        key = (nfft, values.shape[0])
        if key not in self._band_weights:
            freqs = np.log2(np.maximum(np.fft.rfftfreq(nfft, 1.0 / self.sample_rate), 1.0))
            centres = np.log2(125.0 * 2.0 ** np.arange(values.shape[0]))
            eye = np.eye(values.shape[0])
            self._band_weights[key] = np.stack([np.interp(freqs, centres, e) for e in eye])  # (B, F)
        return values.T @ self._band_weights[key]

    def _make_tail(self, src: Source) -> PartitionedConvolver:
        if self._diffuse is None:
            self._diffuse = (self.hrtf.diffuse_field_power(1024), self.hrtf.diffuse_field_coherence(1024))
        power, coherence = self._diffuse
        tail = late_tail(self.room, src.images, self.head_position, diffuse_power=power, coherence=coherence, rng=self.rng, sample_rate=self.sample_rate)
        # The tail starts after its leading zeros; the largest power-of-two partition that
        # fits in them makes streaming latency-free (and at most 512 keeps it cheap).
        nz = np.flatnonzero(np.any(tail != 0, axis=0))
        lead = int(nz[0]) if nz.size else tail.shape[1]
        partition = int(min(512, 2 ** np.floor(np.log2(max(lead, 2)))))
        if partition < 32:
            raise ConfigError(f"room {self.room.name!r}: the late tail starts too early ({lead} samples) to stream")
        tail[:, :partition] = 0.0
        return PartitionedConvolver(tail, partition)

    def impulse_response(self, source_position, *, seconds: float | None = None) -> np.ndarray:
        """The binaural room impulse response (2, n) from ``source_position`` to the ears
        at the current head pose, early plus late, in pressure per unit pressure at 1 m.

        Rendered by streaming a unit impulse through a fresh source, so it is exactly what
        the renderer applies (no noise, no microphone)."""
        probe = BinauralRenderer(self.hrtf, self.room, rng=self.rng, sample_rate=self.sample_rate, background=False, late=self.late)
        probe.head_position, probe.head_rotation = self.head_position, self.head_rotation
        src = probe.add_source("impulse", np.array([1.0]), source_position, level_db=float(20 * np.log10(1 / 20e-6)), start=0)
        if seconds is None:
            tail_len = src.tail.n_part * src.tail.partition + src.tail.partition if src.tail is not None else 0
            seconds = (max(tail_len, probe.early_response(src)[0].shape[1]) + 64) / self.sample_rate
        return probe.render(seconds)


class DirectionLookup:
    """Nearest HRTF direction for any head-frame direction, by table.

    A KD-tree query costs about 1 us per direction in Python; the renderer asks for every
    image source at every block. The table holds the nearest measured direction for the
    centre of every cell of a 0.5 deg azimuth x elevation grid (worst-case extra error
    0.35 deg, far below the HRTF's 5-10 deg spacing).
    """

    STEP = 0.5

    def __init__(self, hrtf) -> None:
        from acoustic_sim.frames import sph_to_vec

        az = np.arange(-180.0, 180.0, self.STEP) + self.STEP / 2
        el = np.arange(-90.0, 90.0, self.STEP) + self.STEP / 2
        grid = sph_to_vec(az[None, :], el[:, None])
        self.table = np.asarray(hrtf.nearest_index(grid.reshape(-1, 3)), dtype=np.int64).reshape(el.size, az.size)

    def lookup(self, unit_vectors: np.ndarray) -> np.ndarray:
        v = unit_vectors
        az = np.arctan2(v[:, 1], v[:, 0]) * (180.0 / np.pi)
        el = np.arcsin(np.clip(v[:, 2], -1.0, 1.0)) * (180.0 / np.pi)
        i = np.minimum(((el + 90.0) / self.STEP).astype(np.int64), self.table.shape[0] - 1)
        j = ((az + 180.0) / self.STEP).astype(np.int64) % self.table.shape[1]
        return self.table[i, j]


class BackgroundNoise:
    """Diffuse background noise at a room's level (dB SPL, unweighted), streamed.

    Spectrum: -4.5 dB per octave above 100 Hz (a typical indoor noise floor between
    pink and brown). Interaural coherence: a diffuse field is coherent at low frequencies
    and incoherent at high ones; a common low-passed component plus independent
    high-passed components with the crossover where the HRTF's diffuse-field coherence
    falls to 0.5 reproduces that with cheap streaming filters.
    """

    def __init__(self, level_db: float, hrtf, rng: np.random.Generator, sample_rate: int) -> None:
        from scipy import signal

        self.rng = rng
        self.gain = float(db_spl_to_pa(level_db))
        coh = hrtf.diffuse_field_coherence(1024)
        freqs = np.fft.rfftfreq(1024, 1.0 / sample_rate)
        below = np.flatnonzero(coh < 0.5)
        fc = float(np.clip(freqs[below[0]] if below.size else 700.0, 200.0, 2000.0))
        self.crossover_hz = fc
        # -4.5 dB/octave tilt: a first-order shelf cascade approximates it over 100 Hz-10 kHz.
        zeros = [-2 * np.pi * f for f in (250.0, 1300.0, 7000.0)]
        poles = [-2 * np.pi * f for f in (100.0, 550.0, 3000.0)]
        z, p, k = signal.bilinear_zpk(zeros, poles, 1.0, sample_rate)
        tilt = signal.zpk2sos(z, p, k)
        low = signal.butter(2, fc, "low", fs=sample_rate, output="sos")
        high = signal.butter(2, fc, "high", fs=sample_rate, output="sos")
        self.sos_common = np.vstack([tilt, low])
        self.sos_side = np.vstack([tilt, high])
        # Normalize to unit total RMS for white input, measured once on a long burst.
        probe = np.random.default_rng(0).standard_normal((3, 1 << 17))
        c = signal.sosfilt(self.sos_common, probe[0])
        sides = signal.sosfilt(self.sos_side, probe[1:], axis=-1)
        self.norm = 1.0 / np.sqrt(np.mean((c + sides[0]) ** 2))
        self.zi_common = np.zeros((self.sos_common.shape[0], 2))
        self.zi_side = np.zeros((2, self.sos_side.shape[0], 2))
        self._signal = signal
        # Warm up the filters so the first block is already stationary.
        self._generate(1 << 14)
        self._buffer = np.zeros((2, 0))

    CHUNK = 8192

    def __call__(self, n: int) -> np.ndarray:
        """The next ``n`` samples (2, n) in Pa. Generated in chunks of :attr:`CHUNK`
        (filter calls have a fixed cost), so the stream does not depend on block sizes."""
        while self._buffer.shape[1] < n:
            self._buffer = np.concatenate([self._buffer, self._generate(self.CHUNK)], axis=1)
        out, self._buffer = self._buffer[:, :n], self._buffer[:, n:]
        return out

    def _generate(self, n: int) -> np.ndarray:
        sig = self._signal
        w = self.rng.standard_normal((3, n))
        c, self.zi_common = sig.sosfilt(self.sos_common, w[0], zi=self.zi_common)
        sides = np.empty((2, n))
        for e in range(2):
            sides[e], self.zi_side[e] = sig.sosfilt(self.sos_side, w[1 + e], zi=self.zi_side[e])
        return (c + sides) * (self.norm * self.gain)
