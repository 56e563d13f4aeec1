"""Streaming convolution kernels the renderer is built from.

- :func:`fractional_hrir_table`: every HRIR pre-shifted by ``q / Q`` of a sample, so that
  placing an image source at a fractional delay is a table lookup plus an integer offset.
- :func:`assemble`: overlap-add many short responses at integer offsets into one, through
  pyroomacoustics' C++ ``libroom.delay_sum`` (the kernel pyroomacoustics itself uses to
  build responses from image sources).
- :class:`PartitionedConvolver`: uniformly partitioned overlap-save convolution of a long,
  fixed, multichannel filter, for the diffuse tail. It accepts blocks of any length and
  has no latency as long as the filter's first ``partition`` samples are zero, which a
  late tail always satisfies (its first partition is dropped).

Written here because no library offers a streaming partitioned convolver that accepts
the 705/706-sample blocks of the project clock; scipy.signal's convolvers are one-shot.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from pyroomacoustics import libroom


def fractional_hrir_table(hrir: np.ndarray, phases: int) -> np.ndarray:
    """HRIRs delayed by ``q / phases`` samples, q = 0..phases-1, interleaved per ear.

    Parameters
    ----------
    hrir : numpy.ndarray, shape (D, 2, K)
    phases : int
        Fractional-delay resolution (1-64). 8 phases keep the delay error under 1/16 of a
        sample (0.13 rad at 15 kHz).

    Returns
    -------
    numpy.ndarray, shape (D, phases, 2 * (K + 1)), float32
        Row ``[d, q]`` holds samples ``t = 0..K`` of both ears interleaved (left, right,
        left, ...), the layout :func:`assemble` adds in one pass.
    """
    d, _, k = hrir.shape
    n = 2 * k  # zero padding keeps the band-limited shift from wrapping around
    spec = np.fft.rfft(hrir, n=n, axis=-1)
    freqs = np.fft.rfftfreq(n)
    frac = np.arange(phases) / phases
    shift = np.exp(-2j * np.pi * freqs[None, :] * frac[:, None])  # (Q, F)
    shifted = np.fft.irfft(spec[:, None, :, :] * shift[None, :, None, :], n=n, axis=-1)[..., : k + 1]
    # (D, Q, 2, K+1) -> (D, Q, K+1, 2) -> interleaved rows
    return np.ascontiguousarray(shifted.transpose(0, 1, 3, 2).reshape(d, phases, 2 * (k + 1)), dtype=np.float32)


def assemble(rows: np.ndarray, offsets: np.ndarray, length: int) -> np.ndarray:
    """Sum interleaved stereo rows (M, 2 * T) placed at sample ``offsets`` (M,) into (2, length)."""
    out = np.zeros(2 * length + rows.shape[1], dtype=np.float32)
    libroom.delay_sum(np.ascontiguousarray(rows, dtype=np.float32), (2 * offsets).astype(np.int32), out, 1)
    return out[: 2 * length].reshape(length, 2).T


class PartitionedConvolver:
    """Stream a multichannel signal through a fixed filter of many partitions.

    Parameters
    ----------
    filters : numpy.ndarray, shape (C, L)
        One filter per output channel, applied to the same mono input. The first
        ``partition`` samples must be zero (checked): that is what lets any block length
        through without latency.
    partition : int
        Partition length in samples (a power of two is fastest).
    """

    def __init__(self, filters: np.ndarray, partition: int) -> None:
        filters = np.atleast_2d(np.asarray(filters, dtype=float))
        if np.any(filters[:, :partition]):
            raise ValueError("the filter's first partition must be zero for latency-free streaming")
        self.partition = p = int(partition)
        self.channels = filters.shape[0]
        n_part = max(1, -(-filters.shape[1] // p))
        padded = np.zeros((self.channels, n_part * p))
        padded[:, : filters.shape[1]] = filters
        parts = padded.reshape(self.channels, n_part, p)[:, 1:, :]  # partition 0 is zero
        self.spectra = sfft.rfft(parts, n=2 * p, axis=-1)  # (C, P-1, p+1)
        self.n_part = parts.shape[1]
        self.fdl = np.zeros((max(self.n_part, 1), p + 1), dtype=complex)  # input spectra, newest first
        self._prev = np.zeros(p)  # last pushed input chunk (overlap-save needs two)
        self._inbuf = np.zeros(0)  # input not yet pushed into the FDL
        self._outbuf = np.zeros((self.channels, 0))  # output produced but not yet returned
        self._pushed = 0  # input chunks in the FDL
        self._produced = 0  # output samples produced

    def process(self, x: np.ndarray) -> np.ndarray:
        """Filter the next ``len(x)`` input samples; returns (C, len(x))."""
        p = self.partition
        x = np.asarray(x, dtype=float)
        self._inbuf = np.concatenate([self._inbuf, x])
        total_in = self._pushed * p + self._inbuf.size
        pieces = [self._outbuf]
        while self._produced < total_in:
            # Output chunk j needs input chunks 0..j-1, complete because j*p <= total_in.
            j = self._produced // p
            while self._pushed < j:
                chunk, self._inbuf = self._inbuf[:p], self._inbuf[p:]
                self.fdl = np.roll(self.fdl, 1, axis=0)
                self.fdl[0] = sfft.rfft(np.concatenate([self._prev, chunk]))
                self._prev = chunk
                self._pushed += 1
            if self.n_part:
                y = np.einsum("kf,ckf->cf", self.fdl[: self.n_part], self.spectra)
                pieces.append(sfft.irfft(y, n=2 * p, axis=-1)[:, p:])
            else:
                pieces.append(np.zeros((self.channels, p)))
            self._produced += p
        out = np.concatenate(pieces, axis=1)
        self._outbuf = out[:, x.size :]
        return out[:, : x.size]
