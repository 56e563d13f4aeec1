"""Streaming convolution kernels the renderer is built from.

- :func:`rfft`, :func:`irfft`, :func:`fft_size`: the small FFTs of the renderer's block loop.
- :func:`fractional_hrir_table`: every HRIR pre-shifted by ``q / Q`` of a sample, so that
  placing an image source at a fractional delay is a table lookup plus an integer offset.
- :func:`assemble`: overlap-add many short responses at integer offsets into one (or
  into one per gain set), as one dense matrix product.
- :class:`PartitionedConvolver`: uniformly partitioned overlap-save convolution of a long,
  fixed, multichannel filter. It accepts blocks of any length and has no latency as long
  as the filter's first ``partition`` samples are zero.
- :class:`FrameConvolver`: the same for a caller that runs its own overlap-save with one
  window per frame (the renderer's late-reverb bus): the frames are the partitions, the
  caller's FFTs are shared, only the multiply-adds remain.

Written here because no library offers a streaming partitioned convolver that accepts
the 705/706-sample blocks of the project clock; scipy.signal's convolvers are one-shot.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.fft as sfft


def _pocketfft():
    """pocketfft's own transforms, which scipy.fft runs behind a backend dispatch that
    costs 3-5 us per call (a dozen Python calls); the renderer makes two to seven small
    transforms per 16 ms block. None (use scipy.fft) unless this SciPy has them, callable
    as scipy.fft calls them, with scipy.fft's results (checked here, once)."""
    try:
        from scipy.fft._pocketfft import pypocketfft

        x = np.random.default_rng(0).standard_normal((2, 12)).astype(np.float32)
        spec = pypocketfft.r2c(x, (1,), True, 0, None, 1)
        back = pypocketfft.c2r(spec, (1,), 12, False, 2, None, 1)
        if spec.dtype == np.complex64 and np.allclose(spec, sfft.rfft(x, axis=-1), atol=1e-5) and np.allclose(back, x, atol=1e-5):
            return pypocketfft
    except Exception:  # noqa: BLE001 - any surprise means: use the public API
        return None
    return None


_POCKETFFT = _pocketfft()


def rfft(x: np.ndarray) -> np.ndarray:
    """Real FFT along the last axis (no padding); float32 in, complex64 out."""
    if _POCKETFFT is None:
        return sfft.rfft(x, axis=-1)
    return _POCKETFFT.r2c(x, (x.ndim - 1,), True, 0, None, 1)


def irfft(spectrum: np.ndarray, n: int) -> np.ndarray:
    """Inverse real FFT of ``n`` points along the last axis; complex64 in, float32 out."""
    if _POCKETFFT is None:
        return sfft.irfft(spectrum, n=n, axis=-1)
    return _POCKETFFT.c2r(spectrum, (spectrum.ndim - 1,), n, False, 2, None, 1)


def fft_size(n: int) -> int:
    """Smallest FFT length >= ``n`` (samples, >= 1) of the form 2**k or 3 * 2**k (both fast
    in pocketfft)."""
    p2 = 1 << max(int(n - 1).bit_length(), 0)
    p3 = 3 * (1 << max(int(-(-n // 3) - 1).bit_length(), 0))
    return min(p2, p3)

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


def assemble(rows: np.ndarray, offsets: np.ndarray, length: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Overlap-add interleaved stereo rows placed at sample offsets.

    Parameters
    ----------
    rows : numpy.ndarray, shape (M, 2 * T)
        Interleaved stereo responses (as in :func:`fractional_hrir_table`).
    offsets : numpy.ndarray of int, shape (M,)
        Start sample of each row; ``offsets + T <= length`` is required.
    length : int
        Output length in samples.
    weights : numpy.ndarray, shape (R, M), optional
        R gain sets: the result is then (R, 2, length), one sum per set, in one pass.

    Returns
    -------
    numpy.ndarray, shape (2, length) or (R, 2, length), in the dtype of ``rows``

    The rows are written once into a dense (M, span) matrix at their offsets (the span
    from the earliest to the latest sample any row reaches), and one matrix product with
    the weights sums every set (faster than ``numpy.bincount``, slice additions or
    pyroomacoustics' ``libroom.delay_sum``; measurements: docs/notes/renderer.md).
    """
    rows = np.asarray(rows)
    m, width = rows.shape
    offsets = np.asarray(offsets, np.int64)
    single = weights is None
    w = np.ones((1, m), rows.dtype) if single else np.atleast_2d(np.asarray(weights)).astype(rows.dtype, copy=False)
    out = np.zeros((w.shape[0], 2 * length), rows.dtype)
    if m:
        lo, span, flat, matrices = _placement(offsets.tobytes(), width)
        placed = matrices.get(rows.dtype)
        if placed is None:  # zero where no row lands; rows always land on the same places
            placed = matrices[rows.dtype] = np.zeros((m, span), rows.dtype)
        placed.ravel()[flat] = rows.ravel()
        out[:, 2 * lo : 2 * lo + span] = w @ placed
    out = out.reshape(-1, length, 2).transpose(0, 2, 1)
    return out[0] if single else out


@functools.lru_cache(maxsize=16)
def _placement(offsets: bytes, width: int) -> tuple[int, int, np.ndarray, dict]:
    """Where rows of ``width`` interleaved samples land in a dense (M, span) matrix: the
    first sample ``lo``, the span, the flat indices, and the matrix itself per dtype
    (cached: offsets repeat while the geometry stands still, and then only the rows'
    values need writing)."""
    off = np.frombuffer(offsets, np.int64)
    lo = int(off.min())
    span = 2 * (int(off.max()) - lo) + width
    flat = ((2 * (off - lo) + span * np.arange(off.size))[:, None] + np.arange(width)[None, :]).ravel()
    return lo, span, flat, {}


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
        # Input spectra, stored twice so that the newest-first window is always a view.
        self._ring = np.zeros((2 * max(self.n_part, 1), p + 1), dtype=np.complex64)
        self._head = 0
        self.spectra = self.spectra.astype(np.complex64)
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
                k = max(self.n_part, 1)
                self._head = (self._head - 1) % k
                self._ring[self._head] = self._ring[self._head + k] = sfft.rfft(np.concatenate([self._prev, chunk]))
                self._prev = chunk
                self._pushed += 1
            if self.n_part:
                window = self._ring[self._head : self._head + self.n_part]  # newest first
                y = (window[None] * self.spectra).sum(axis=1)
                pieces.append(sfft.irfft(y, n=2 * p, axis=-1)[:, p:])
            else:
                pieces.append(np.zeros((self.channels, p)))
            self._produced += p
        out = np.concatenate(pieces, axis=1)
        self._outbuf = out[:, x.size :]
        return out[:, : x.size]


class FrameConvolver:
    """Stream a mono signal through a fixed multichannel filter on the FFT grid of an
    overlap-save whose hop is the (varying) frame length: the partitions are the frames.

    For a frame of ``n0`` samples that follows frames of ``n1, n2, ...`` samples (most
    recent first), partition k is the filter's taps ``[A_k, A_k + n_k)`` with
    ``A_k = n0 + n1 + ... + n_(k-1)``, applied to the spectrum ``X_k`` of the N-sample
    input window that ended with frame k; the frame's output is the last ``n0`` samples of
    ``irfft(sum_k X_k G_k)``. That is the slice an overlap-save with windows of N samples
    takes, so a caller that already transforms those windows (the renderer's early
    overlap-save) passes its spectra in (:meth:`push`) and adds :meth:`output` to its own
    spectrum before its inverse FFT: the long filter then costs its multiply-adds only, no
    FFT. Partition spectra are computed once per pattern of frame lengths (the project
    clock's 705/706 frames repeat every 5) and kept.

    Exact when the filter is zero on its first ``n0`` taps (no partition needs the frame
    being rendered) and ``n0 + n_k - 1 <= N`` for every k; both are checked.

    Parameters
    ----------
    filters : numpy.ndarray, shape (C, L)
        One filter per output channel, applied to the same mono input.
    """

    def __init__(self, filters: np.ndarray) -> None:
        self.filters = np.atleast_2d(np.asarray(filters, dtype=float))
        self.channels, self.length = self.filters.shape
        nonzero = np.flatnonzero(np.any(self.filters != 0, axis=0))
        self.lead = int(nonzero[0]) if nonzero.size else self.length  # leading zero taps
        self.nfft = 0
        self._lengths: list[int] = []  # lengths of the pushed frames still needed, most recent first
        self._kept: tuple = ()  # the same, as a key
        self._ring = np.zeros((0, 1), np.complex64)  # their spectra, once per channel, stored twice (see push)
        self._head = 0
        self._pieces: dict = {}
        self._stacks: dict = {}
        self._buffer = np.zeros(0, np.float32)  # input samples, for re-gridding
        self._fill = 0

    def set_fft_size(self, nfft: int) -> None:
        """Move to windows of ``nfft`` samples: the kept input windows are transformed
        again and the partition spectra recomputed."""
        nfft = int(nfft)
        if nfft == self.nfft:
            return
        self.nfft = nfft
        self._pieces, self._stacks = {}, {}
        count = len(self._lengths)
        self._ring = np.zeros((2 * max(count, 1), self.channels * (nfft // 2 + 1)), np.complex64)
        self._head = 0
        end = self._history.size
        for k, n in enumerate(self._lengths):
            self._ring[k] = self._ring[k + count] = np.tile(self._window_spectrum(end), self.channels)
            end -= n

    def feed(self, x: np.ndarray) -> None:
        """Keep input samples (mono) for :meth:`set_fft_size`; every sample, in order."""
        keep = self.length + max(self.nfft, 4096)  # what re-gridding reads back
        if self._buffer.size < 2 * keep + x.size:
            grown = np.zeros(4 * keep + x.size, np.float32)
            grown[: self._fill] = self._buffer[: self._fill]
            self._buffer = grown
        if self._fill + x.size > self._buffer.size:
            self._buffer[:keep] = self._buffer[self._fill - keep : self._fill]
            self._fill = keep
        self._buffer[self._fill : self._fill + x.size] = x
        self._fill += x.size

    @property
    def _history(self) -> np.ndarray:
        return self._buffer[: self._fill]

    def output(self, n: int) -> np.ndarray | None:
        """Spectrum (C, nfft//2+1), complex64, whose inverse FFT ends with the output of
        the next frame of ``n`` samples; None when no input has been pushed."""
        if not self._lengths:
            return None
        if n > self.lead:
            raise ValueError(f"a frame of {n} samples needs the filter's first {n} taps to be zero (it has {self.lead})")
        key = (n,) + self._kept  # may name one frame more than the taps reach: its partition is empty
        stack = self._stacks.get(key)
        if stack is None:
            stack = self._stack(key)
        # (K, C*F), the input repeated per channel: 30% faster than broadcasting (K, 1, F)
        # against (K, C, F), and no BLAS (whose threads stall on a busy machine).
        window = self._ring[self._head : self._head + stack.shape[0]]
        return (window * stack).sum(axis=0).reshape(self.channels, -1)

    def push(self, spectrum: np.ndarray, n: int) -> None:
        """Add the rFFT (nfft//2+1,) of the N-sample input window that ends with the frame
        of ``n`` samples just completed."""
        if not self.nfft:
            raise ValueError("set_fft_size before pushing spectra")
        lengths = [int(n)] + self._lengths
        keep, reach = 0, 1  # a frame needs the pushed ones its taps reach (frames >= 1 sample)
        for m in lengths:
            if reach >= self.length:
                break
            keep += 1
            reach += m
        self._lengths = lengths[: max(keep, 1)]
        self._kept = tuple(self._lengths)
        cap = self._ring.shape[0] // 2
        if len(self._lengths) > cap:  # grow, keeping the order (newest first)
            old = self._ring[self._head : self._head + cap].copy()
            cap = 2 * len(self._lengths)
            self._ring = np.zeros((2 * cap, self.channels * (self.nfft // 2 + 1)), np.complex64)
            self._ring[1 : 1 + old.shape[0]] = old
            self._ring[cap + 1 : cap + 1 + old.shape[0]] = old
            self._head = 1
        # Newest at _head, older after it; stored twice so that any window is one view.
        self._head = (self._head - 1) % cap
        self._ring[self._head].reshape(self.channels, -1)[:] = spectrum
        self._ring[self._head + cap] = self._ring[self._head]

    def process(self, x: np.ndarray) -> np.ndarray:
        """One frame on its own, with its own FFTs: the output (C, len(x)) for input ``x``."""
        if not self.nfft:
            raise ValueError("set_fft_size before processing")
        n = x.size
        self.feed(x)
        spec = self.output(n)
        y = np.zeros((self.channels, n)) if spec is None else sfft.irfft(spec, n=self.nfft, axis=-1)[:, -n:].astype(float)
        self.push(self._window_spectrum(self._history.size), n)
        return y

    def _window_spectrum(self, end: int) -> np.ndarray:
        window = self._history[max(end - self.nfft, 0) : end]
        return sfft.rfft(np.pad(window, (self.nfft - window.size, 0)))

    def _stack(self, key: tuple) -> np.ndarray:
        """Partition spectra (K, C*F) for frame lengths ``key`` (the frame to render first);
        partitions past the filter's end are left out."""
        n0 = key[0]
        start = n0
        parts = []
        for m in key[1:]:
            if start >= self.length:
                break
            if n0 + m - 1 > self.nfft:
                raise ValueError(f"frames of {n0} and {m} samples need windows of {n0 + m - 1} samples, more than {self.nfft}")
            piece = self._pieces.get((start, m))
            if piece is None:
                piece = self._pieces[(start, m)] = sfft.rfft(self.filters[:, start : start + m], n=self.nfft, axis=-1).astype(np.complex64)
            parts.append(piece)
            start += m
        stack = np.stack(parts).reshape(len(parts), -1) if parts else np.zeros((0, self.channels * (self.nfft // 2 + 1)), np.complex64)
        if len(self._stacks) >= 64:
            self._stacks.clear()
        self._stacks[key] = stack
        return stack
