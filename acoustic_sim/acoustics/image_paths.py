"""Sound paths from a source to the ears: the direct path and the reflections, as spectra.

For the current head pose, each path is an HRIR of its direction in the head frame, a
delay (whole samples plus one of :data:`FRACTIONAL_PHASES` fractions, taken from a
pre-shifted HRIR table) and a gain (1/r, and for a reflection its walls' band damping).
:class:`PathResponses` turns a source's paths into the rFFT of its early response on the
renderer's FFT grid; :class:`ReflectionSchedule` says when the reflections are due again.

The direct path (image 0) is recomputed every block and uses the full HRIR; reflections
(images 1..) use the first ``reflection_taps`` samples of theirs (faded out: nearly all of
the energy and the direction cues, at a quarter of the cost), and are re-rendered at a
lower rate, as interactive room-acoustics engines do: the direct sound carries the
localization cues. When the head turns, every reflection's direction turns with it and
its delay stays; a displacement changes a delay by at most its length. So the defaults
(5 deg, 5 cm, 4 blocks = 64 ms) keep a turning head's reflections within the KEMAR grid's
own 5 deg azimuth spacing of where per-block updates would put them. Measurements:
docs/notes/renderer.md.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.fft as sfft

from acoustic_sim.acoustics.convolution import assemble, fft_size, rfft
from acoustic_sim.acoustics.hrtf_tables import FRACTIONAL_PHASES
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SPEED_OF_SOUND


class ReflectionSchedule:
    """When a source's reflections are re-rendered.

    Parameters
    ----------
    interval : int
        While the head or the source moves, re-render at least every this many blocks;
        an integer >= 1 (1 = every block).
    turn_deg : float
        Re-render at once when the head has turned more than this since the last update;
        deg, 0-180 (0 = at every change).
    move_m : float
        Likewise when the head or the source has moved more than this; m, 0-10.

    Raises
    ------
    ConfigError
        A parameter out of its range.
    """

    def __init__(self, interval: int, turn_deg: float, move_m: float) -> None:
        if not isinstance(interval, (int, np.integer)) or interval < 1:
            raise ConfigError(f"reflection_interval must be an integer >= 1 (blocks), got {interval!r}")
        if not 0.0 <= turn_deg <= 180.0:
            raise ConfigError(f"reflection_turn_deg must be 0..180 deg, got {turn_deg}")
        if not 0.0 <= move_m <= 10.0:
            raise ConfigError(f"reflection_move_m must be 0..10 m, got {move_m}")
        self.interval = int(interval)
        self.turn_deg = float(turn_deg)
        self.move_m = float(move_m)
        self._turn_cos = math.cos(math.radians(self.turn_deg))

    def due(self, last: tuple | None, head: tuple, rot: tuple, where: tuple, blocks: int) -> bool:
        """Whether to re-render the reflections this block.

        Parameters
        ----------
        last : tuple or None
            ``(head, rot, where, block)`` of the last update, None before the first.
        head : tuple of 3 float
            Head centre now, m (room frame).
        rot : tuple of 9 float
            Head rotation now, the 3x3 head-to-room matrix, row-major.
        where : tuple of 3 float
            Source position now, m (room frame).
        blocks : int
            Blocks rendered so far, >= 0.

        Returns
        -------
        bool
        """
        if last is None:
            return True
        head0, rot0, where0, block = last
        if head0 == head and rot0 == rot and where0 == where:
            return False
        if blocks - block >= self.interval:
            return True
        if math.dist(head0, head) > self.move_m or math.dist(where0, where) > self.move_m:
            return True
        a, b = rot0, rot  # cos of the rotation angle between the poses: (trace(A^T B) - 1) / 2
        cos = 0.5 * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5] + a[6] * b[6] + a[7] * b[7] + a[8] * b[8] - 1.0)
        return cos < self._turn_cos


class PathResponses:
    """Geometry and spectra of sources' direct paths and reflections, for one HRTF.

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        The ears (its ``onset_samples`` is taken off every delay).
    tables : acoustic_sim.acoustics.hrtf_tables.HRTFTables
        The HRTF's shared derived tables (pre-shifted HRIRs, direction lookup).
    sample_rate : int
        Hz, the HRTF's rate (> 0).
    reflection_taps : int
        HRIR length used for reflections, samples, 4 to the HRIR length (longer is cut to it).

    Raises
    ------
    ConfigError
        ``reflection_taps`` out of range.
    """

    def __init__(self, hrtf, tables, sample_rate: int, reflection_taps: int) -> None:
        self.onset = hrtf.onset_samples
        self.sample_rate = sample_rate
        self.table = tables.hrir
        self.taps = tables.taps
        short = min(reflection_taps, hrtf.hrir.shape[-1])
        self.short = tables.short_hrir(short)
        self.short_taps = short + 1
        self.directions = tables.directions
        self._band_weights: dict = {}
        self._scratch: dict = {}

    # -- geometry -------------------------------------------------------------------------
    def direct(self, src, head: tuple, rot: tuple) -> tuple:
        """The direct path for a head pose. Scalar arithmetic: it runs every block.

        Parameters
        ----------
        src : acoustic_sim.acoustics.render_source.Source
            The source (its ``position``, m, room frame, at least 0.15 m from the head).
        head : tuple of 3 float
            Head centre, m (room frame).
        rot : tuple of 9 float
            Head-to-room rotation, row-major.

        Returns
        -------
        key : tuple
            (HRIR index, whole delay in samples, fractional phase 0..FRACTIONAL_PHASES-1,
            distance in m).
        length : int
            Samples of response the path needs.

        Raises
        ------
        ConfigError
            The source is closer than 0.15 m to the head centre.
        """
        hx, hy, hz = head
        sx, sy, sz = src.position.tolist()
        rx, ry, rz = sx - hx, sy - hy, sz - hz
        dist = math.sqrt(rx * rx + ry * ry + rz * rz)
        if dist < 0.15:
            raise ConfigError(f"source {src.name!r} is {dist:.3f} m from the head centre: closer than 0.15 m is inside the head")
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rot
        # head frame = rel @ R (R maps head to room)
        vx, vy, vz = (rx * r00 + ry * r10 + rz * r20) / dist, (rx * r01 + ry * r11 + rz * r21) / dist, (rx * r02 + ry * r12 + rz * r22) / dist
        idx = self.directions.lookup_one(vx, vy, vz)
        delay = max(dist / SPEED_OF_SOUND * self.sample_rate - self.onset, 0.0)
        whole = math.floor(delay)
        phase = round((delay - whole) * FRACTIONAL_PHASES)
        whole += phase // FRACTIONAL_PHASES
        phase %= FRACTIONAL_PHASES
        return (idx, whole, phase, dist), whole + self.taps

    def reflections(self, src, head: tuple, head_position: np.ndarray, head_rotation: np.ndarray) -> tuple:
        """The reflections (images 1..) for a head pose.

        Everything but the directions depends on positions only and is kept on ``src``
        while the head and the source stand still (a turning head recomputes the
        directions alone).

        Parameters
        ----------
        src : acoustic_sim.acoustics.render_source.Source
            The source, with its ``images``; every image at least 0.15 m from the head.
        head : tuple of 3 float
            ``head_position`` as a tuple, m.
        head_position : numpy.ndarray, shape (3,)
            Head centre, m (room frame).
        head_rotation : numpy.ndarray, shape (3, 3)
            Head-to-room rotation.

        Returns
        -------
        tuple
            ``(idx, whole, phase, weights, key, length)``: per image (M-1 of them) the HRIR
            index, whole delay (samples) and fractional phase, arrays of shape (M-1,); the
            gains per band shape (R, M-1); a key (bytes) that changes whenever the response
            does; the response length in samples.

        Raises
        ------
        ConfigError
            An image closer than 0.15 m to the head centre.
        """
        where = (head, tuple(src.position.tolist()))
        if src.placement is None or src.placement[0] != where:
            images = src.images.at(src.position)[1:]
            rel = images - head_position
            dist = np.sqrt((rel * rel).sum(axis=1))
            if dist.size and dist.min() < 0.15:
                raise ConfigError(f"source {src.name!r} has an image {dist.min():.3f} m from the head centre: closer than 0.15 m is inside the head")
            delay = np.maximum(dist * (self.sample_rate / SPEED_OF_SOUND) - self.onset, 0.0)
            whole = np.floor(delay).astype(np.int64)
            phase = np.rint((delay - whole) * FRACTIONAL_PHASES).astype(np.int64)
            whole += phase // FRACTIONAL_PHASES
            phase %= FRACTIONAL_PHASES
            weights = self.band_factors(src)[1] / dist if dist.size else np.zeros((1, 0))
            static = whole.tobytes() + phase.tobytes() + dist.astype(np.float32).tobytes()
            length = int(whole.max()) + self.short_taps if dist.size else 0
            src.placement = (where, rel / dist[:, None], whole, phase, weights, static, length)
        _, unit, whole, phase, weights, static, length = src.placement
        idx = self.directions.lookup(unit @ head_rotation) if whole.size else whole
        return idx, whole, phase, weights, idx.tobytes() + static, length

    def band_factors(self, src) -> tuple:
        """The reflections' per-band damping (B, M-1) of ``src``, factored once per source
        into a few spectral shapes (SVD, 99.9% of the energy).

        Parameters
        ----------
        src : acoustic_sim.acoustics.render_source.Source
            The source, with its ``images`` (the factors are cached on it).

        Returns
        -------
        tuple
            ``(shapes, weights)``: shapes (B, R), or None for a frequency-flat room, and
            weights (R, M-1).
        """
        if src.band_factors is None:
            damping = src.images.damping[:, 1:]
            if damping.shape[0] == 1:
                src.band_factors = (None, damping)
            else:
                u, sv, vt = np.linalg.svd(damping, full_matrices=False)
                rank = int(np.searchsorted(np.cumsum(sv**2) / np.sum(sv**2), 0.999) + 1)
                src.band_factors = (u[:, :rank], sv[:rank, None] * vt[:rank])
        return src.band_factors

    def early_response(self, src, pose: tuple) -> tuple[np.ndarray, tuple]:
        """The early response of ``src`` (direct path and reflections, freshly computed).

        Parameters
        ----------
        src : acoustic_sim.acoustics.render_source.Source
            The source.
        pose : tuple
            ``(head, rot, head_position, head_rotation)`` as in :meth:`direct` and
            :meth:`reflections`.

        Returns
        -------
        tuple
            ``(response, key)``: the response, shape (2, L), float64, in pressure at the
            ears per unit pressure at 1 m, and a key that changes whenever it does.
        """
        head, rot, head_position, head_rotation = pose
        direct, direct_len = self.direct(src, head, rot)
        reflections = self.reflections(src, head, head_position, head_rotation)
        length = max(direct_len, reflections[-1])
        nfft = fft_size(length)
        early_only = dataclasses.replace(src, tail_head=None, tail_spectrum=None)
        spec = self.direct_spectrum(direct, nfft) + self.reflection_spectrum(early_only, reflections, nfft)
        h = sfft.irfft(spec, n=nfft, axis=-1)[:, :length].astype(np.float64)
        return h, (direct, reflections[-2])

    # -- spectra --------------------------------------------------------------------------
    def _scratch_buffer(self, nfft: int) -> np.ndarray:
        if nfft not in self._scratch:
            self._scratch = {nfft: np.zeros((2, nfft), np.float32)}
        return self._scratch[nfft]

    def direct_spectrum(self, direct: tuple, nfft: int) -> np.ndarray:
        """rFFT of the direct path: the full HRIR at its delay, times 1/r.

        Parameters
        ----------
        direct : tuple
            The key from :meth:`direct`.
        nfft : int
            FFT size, samples, at least the path's length.

        Returns
        -------
        numpy.ndarray, shape (2, nfft // 2 + 1), complex64
        """
        idx, whole, phase, dist = direct
        buf = self._scratch_buffer(nfft)
        taps = self.taps
        buf[:, whole : whole + taps] = self.table[idx, phase].reshape(taps, 2).T
        buf[:, whole : whole + taps] *= np.float32(1.0 / dist)
        spec = rfft(buf)
        buf[:, whole : whole + taps] = 0.0
        return spec

    def reflection_spectrum(self, src, reflections: tuple, nfft: int) -> np.ndarray:
        """rFFT of the reflections plus the source's tail head (``src.tail_head``, if any).

        Images are overlap-added straight onto the FFT grid (:func:`assemble`). With
        frequency-dependent walls each band shape's image gains go into their own sum,
        which is then shaped by its band response. Spreading (1/r) scales images, not bands.

        Parameters
        ----------
        src : acoustic_sim.acoustics.render_source.Source
            The source (its tail head's spectrum is cached on it).
        reflections : tuple
            From :meth:`reflections`.
        nfft : int
            FFT size, samples, at least the response's length.

        Returns
        -------
        numpy.ndarray, shape (2, nfft // 2 + 1), complex64
        """
        idx, whole, phase, weights, _, _ = reflections
        shapes = self.band_factors(src)[0]
        if idx.size:
            parts_spec = rfft(assemble(self.short[idx, phase], whole, nfft, weights))  # (R, 2, F)
            spec = parts_spec[0] if shapes is None else (self._band_shapes(shapes, nfft)[:, None, :] * parts_spec).sum(axis=0)
        else:
            spec = np.zeros((2, nfft // 2 + 1), np.complex64)
        if src.tail_head is not None:
            if src.tail_spectrum is None or src.tail_spectrum.shape[-1] != nfft // 2 + 1:
                src.tail_spectrum = sfft.rfft(src.tail_head.astype(np.float32), n=nfft, axis=-1)
            spec = spec + src.tail_spectrum
        return spec

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
