"""Whole recordings from a file, block by block: what ``acoustic-sim localize`` and ``detect`` run.

A recording is read :data:`BLOCK_SAMPLES` samples at a time (resampled to the pipeline's
44.1 kHz where the file has another rate, :class:`StreamResampler`), cut into ear frames by
the streaming front end (:class:`~acoustic_sim.auditory.frontend.EarFrontEnd`, bit for bit
the frames of :func:`~acoustic_sim.auditory.frontend.analyze`), and the frames are handed on
in chunks of :data:`CHUNK_FRAMES`. What a command keeps between chunks does not grow with the
file: the last ``window`` frames (spectra or existence maps) for the running estimates, the
last 24 mel frames for the MelCNN's patches, and running sums for the overall result. So
memory is the same for 2 s and for an hour (``docs/notes/streaming.md`` has the numbers).

The samples are those of the in-memory functions, which hold the whole recording (a file
at 44.1 kHz is read as is; another rate is resampled by :class:`StreamResampler`, which gives
``scipy.signal.resample_poly``'s output exactly). The running estimates
(:class:`SSDENetTrack`, :class:`BaselineTrack`, :class:`DetectTrack`) and how they agree with
the in-memory results are in :mod:`~acoustic_sim.auditory.recording_tracks`, re-exported here.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from math import gcd
from pathlib import Path

import numpy as np

from acoustic_sim.auditory.frontend import EarFrontEnd, Frames
from acoustic_sim.auditory.recording_tracks import DETECT_BATCH, BaselineTrack, DetectTrack, SSDENetTrack
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

__all__ = [
    "BLOCK_SAMPLES",
    "CHUNK_FRAMES",
    "DETECT_BATCH",
    "BaselineTrack",
    "DetectTrack",
    "SSDENetTrack",
    "StreamResampler",
    "frame_chunks",
    "wav_blocks",
    "wav_info",
]

BLOCK_SAMPLES = 1 << 16
"""Samples (per channel) read from the file at a time: 1.5 s at 44.1 kHz, 1 MB as float64."""

CHUNK_FRAMES = 256
"""Ear frames handed on at a time (4.1 s; 4 MB of spectra): the MelCNN's batch."""


class StreamResampler:
    """``scipy.signal.resample_poly`` of a long signal, pushed in blocks.

    The output is exactly that of ``resample_poly(x, up, down, axis=0)`` on the whole signal
    (the same filter, the same arithmetic: each output sample is computed by
    ``scipy.signal.upfirdn`` from the same input samples in the same order), while holding
    only the input samples that later outputs still need (about the filter's length over
    ``up``, plus ``down``).

    Parameters
    ----------
    rate_in, rate_out : int
        Sample rates (Hz) of the input and the output.
    n_in : int
        Total input samples (the output length, and the filter's tail padding, depend on it).
    """

    def __init__(self, rate_in: int, rate_out: int, n_in: int) -> None:
        from scipy.signal import firwin
        from scipy.signal._upfirdn import _output_len

        if rate_in <= 0 or rate_out <= 0 or n_in < 0:
            raise ConfigError(f"resampling needs positive rates and n_in >= 0, got {rate_in}, {rate_out}, {n_in}")
        g = gcd(int(rate_out), int(rate_in))
        self.up, self.down = int(rate_out) // g, int(rate_in) // g
        up, down = self.up, self.down
        self.n_in = int(n_in)
        self.n_out = -(-self.n_in * up // down)
        # The filter of resample_poly (scipy 1.17, signal/_signaltools.py), default window.
        max_rate = max(up, down)
        half_len = 10 * max_rate
        h = firwin(2 * half_len + 1, 1.0 / max_rate, window=("kaiser", 5.0)).astype(np.float64)
        h *= up
        n_pre_pad = down - half_len % down
        n_post_pad = 0
        self.n_pre_remove = (half_len + n_pre_pad) // down
        while _output_len(h.shape[0] + n_pre_pad + n_post_pad, self.n_in, up, down) < self.n_out + self.n_pre_remove:
            n_post_pad += 1
        self.h = np.concatenate([np.zeros(n_pre_pad), h, np.zeros(n_post_pad)])
        self._buffer = np.zeros((0, 2))  # input samples [start, start + len)
        self._start = 0  # a multiple of down, so that a chunk's outputs fall on the whole signal's
        self._seen = 0  # input samples pushed
        self._next = 0  # next upfirdn output index M to hand out (before n_pre_remove is dropped)

    def push(self, block: np.ndarray) -> np.ndarray:
        """Append input samples (n, 2); returns the output samples (m, 2) they complete."""
        from scipy.signal import upfirdn

        block = np.asarray(block, np.float64)
        if block.ndim != 2 or block.shape[1] != 2:
            raise ConfigError(f"resampler blocks must have shape (n, 2), got {block.shape}")
        self._seen += block.shape[0]
        if self._seen > self.n_in:
            raise ConfigError(f"more input than announced ({self._seen} > {self.n_in} samples)")
        self._buffer = np.concatenate([self._buffer, block]) if self._buffer.size else block
        end = self._start + self._buffer.shape[0]
        last = self.n_pre_remove + self.n_out  # upfirdn outputs [n_pre_remove, last) are kept
        up, down, taps = self.up, self.down, self.h.size
        if end == self.n_in:  # the end: outputs may use the (zero) samples after it, as in the whole signal
            m_hi = last
        else:  # output M uses inputs i with M*down - taps < i*up <= M*down: all of them must have arrived
            m_hi = min(last, (end * up - 1) // down + 1)
        if m_hi <= self._next:
            return np.zeros((0, 2))
        y = upfirdn(self.h, self._buffer, up, down, axis=0, mode="constant", cval=0)
        offset = self._start * up // down  # chunk output 0 is whole-signal output `offset`
        out = y[self._next - offset : m_hi - offset]
        lo = max(self._next, self.n_pre_remove)  # drop the filter's delay at the start
        out = out[lo - self._next :]
        self._next = m_hi
        # Keep what output m_hi onwards needs: inputs from ceil((m_hi*down - taps + 1) / up),
        # from a multiple of down.
        need = max(0, -(-(m_hi * down - taps + 1) // up))
        start = min(need, end) // down * down
        if start > self._start:
            self._buffer = self._buffer[start - self._start :].copy()
            self._start = start
        return out


def wav_info(path: Path):
    """``soundfile.info`` of ``path``, its errors as ConfigError."""
    import soundfile as sf

    try:
        return sf.info(str(path))
    except (RuntimeError, sf.LibsndfileError) as exc:
        raise ConfigError(f"{path}: not a readable audio file ({str(exc).splitlines()[0]})") from None


def wav_blocks(path: Path, *, block: int = BLOCK_SAMPLES) -> Iterator[np.ndarray]:
    """The samples of a 2-channel sound file at the pipeline's rate, (2, n) float64 blocks.

    At most ``block`` samples per channel are read from the file at a time (and a block
    holds at most about ``block * 44100 / rate`` samples); a file at another rate than
    44.1 kHz is resampled as ``scipy.signal.resample_poly`` would resample the whole file
    (:class:`StreamResampler`).
    """
    import soundfile as sf

    if block < 1:
        raise ConfigError(f"block must be >= 1, got {block}")
    try:
        with sf.SoundFile(str(path)) as f:
            if f.channels != 2:
                raise ConfigError(f"{path}: needs 2 channels (left, right), has {f.channels}")
            resampler = None if f.samplerate == SAMPLE_RATE else StreamResampler(f.samplerate, SAMPLE_RATE, f.frames)
            while True:
                data = f.read(block, dtype="float64", always_2d=True)
                if data.shape[0] == 0:
                    break
                if resampler is not None:
                    data = resampler.push(data)
                if data.shape[0]:
                    yield data.T
    except (RuntimeError, sf.LibsndfileError) as exc:
        raise ConfigError(f"{path}: not a readable audio file ({str(exc).splitlines()[0]})") from None


def frame_chunks(blocks: Iterable[np.ndarray], *, chunk: int = CHUNK_FRAMES) -> Iterator[Frames]:
    """Ear frames of a stream of (2, n) sample blocks, ``chunk`` frames at a time (the last
    chunk may be shorter). Frame k is the frame of the whole recording's
    :func:`~acoustic_sim.auditory.frontend.analyze`, bit for bit."""
    if chunk < 1:
        raise ConfigError(f"chunk must be >= 1, got {chunk}")
    frontend = EarFrontEnd()
    pending: list[Frames] = []
    held = 0
    for block in blocks:
        frames = frontend.push(block)
        if len(frames):
            pending.append(frames)
            held += len(frames)
        while held >= chunk:
            joined = _join(pending)
            yield Frames(joined.index[:chunk], joined.time_s[:chunk], joined.spectra[:chunk])
            rest = Frames(joined.index[chunk:], joined.time_s[chunk:], joined.spectra[chunk:].copy())
            pending, held = ([rest] if len(rest) else []), len(rest)
    if held:
        yield _join(pending)


def _join(parts: list[Frames]) -> Frames:
    if len(parts) == 1:
        return parts[0]
    return Frames(np.concatenate([p.index for p in parts]), np.concatenate([p.time_s for p in parts]),
                  np.concatenate([p.spectra for p in parts]))
