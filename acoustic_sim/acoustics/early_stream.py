"""The renderer's early overlap-save: every source's input history and applied response.

Each source owns one row of the input history and one applied response spectrum (direct
path, reflections and its own tail head, summed), on one FFT size shared by all sources
that grows (never shrinks) when a longer response appears. Every block the direct paths
are brought up to date, and the reflections when due
(:mod:`~acoustic_sim.acoustics.image_paths`). A block is filtered with the old responses
and, where a response changed, with the new one too, cross-faded over the block (raised
cosine): exact time-varying filtering with the response interpolated across the block, so
no clicks. The cross-fade is linear in the sources, so all sources share one inverse FFT
of both. Arithmetic is float32/complex64, in preallocated buffers.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.fft as sfft

from acoustic_sim.acoustics.convolution import fft_size, irfft, rfft
from acoustic_sim.errors import ConfigError

HISTORY = 1 << 14
"""Input samples kept per source for the early response (longer responses are refused)."""


def check_history(hrtf, max_block: int, sample_rate: int) -> None:
    """Refuse an HRTF whose HRIRs plus a block do not fit the :data:`HISTORY` streamed
    (it would fail at the first block).

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        The ears (``n_taps`` samples per HRIR).
    max_block : int
        Longest block, samples (>= 1).
    sample_rate : int
        Hz (> 0), for the message.

    Raises
    ------
    ConfigError
        The HRIRs are too long.
    """
    if fft_size(hrtf.n_taps + max_block) > HISTORY:
        raise ConfigError(
            f"HRTF {hrtf.name!r} has HRIRs of {hrtf.n_taps} samples ({1e3 * hrtf.n_taps / sample_rate:.0f} ms); "
            f"with blocks of up to {max_block} samples the renderer streams responses (HRIR plus "
            f"propagation delay) of at most {HISTORY - max_block} samples: use shorter HRIRs or a smaller max_block"
        )


class EarlyStream:
    """Input rows, applied spectra and the FFT size of the early overlap-save.

    Parameters
    ----------
    max_block : int
        Longest block written at once, samples (>= 1).

    Attributes
    ----------
    inputs : numpy.ndarray, shape (S, 2 * HISTORY + 4 * max_block), float32
        Pressure at 1 m (Pa) per source row; the newest sample is at ``pos - 1``.
    spectra : numpy.ndarray, shape (S, 2, nfft // 2 + 1), complex64
        The responses applied now, per source row.
    nfft : int
        The FFT size, samples (0 before the first response).
    """

    def __init__(self, max_block: int) -> None:
        self.inputs = np.zeros((0, 2 * HISTORY + 4 * max_block), np.float32)
        self.pos = HISTORY  # write position in inputs (HISTORY samples of past before it)
        self.spectra = np.zeros((0, 2, 1), np.complex64)
        self.nfft = 0

    def add_row(self) -> int:
        """A new source's row: silent input, zero response.

        Returns
        -------
        int
            Its index, S - 1.
        """
        self.inputs = np.concatenate([self.inputs, np.zeros((1, self.inputs.shape[1]), np.float32)])
        self.spectra = np.concatenate([self.spectra, np.zeros((1,) + self.spectra.shape[1:], np.complex64)])
        return self.inputs.shape[0] - 1

    def remove_row(self, row: int, sources) -> None:
        """Drop a source's row and renumber the others.

        Parameters
        ----------
        row : int
            The row, 0 to S - 1.
        sources : iterable of acoustic_sim.acoustics.render_source.Source
            The remaining sources, in row order.
        """
        keep = np.arange(self.inputs.shape[0]) != row
        self.inputs, self.spectra = self.inputs[keep], self.spectra[keep]
        for i, other in enumerate(sources):
            other.row = i

    def write(self, sources, sample: int, n: int) -> None:
        """Append every source's next samples to its row.

        Parameters
        ----------
        sources : list of acoustic_sim.acoustics.render_source.Source
            The sources (each writes its ``row``).
        sample : int
            First sample, on the project clock (>= 0).
        n : int
            Samples, 1 to ``max_block``.
        """
        pos = self.pos
        if pos + n > self.inputs.shape[1]:
            self.inputs[:, :HISTORY] = self.inputs[:, pos - HISTORY : pos]
            pos = HISTORY
        for src in sources:
            self.inputs[src.row, pos : pos + n] = src.emitted(sample, n)
        self.pos = pos + n

    def recent(self, n: int) -> np.ndarray:
        """The last ``n`` (1 to ``max_block``) input samples summed over the sources.

        Returns
        -------
        numpy.ndarray, shape (n,), float32
            Pa at 1 m.
        """
        pos = self.pos
        return self.inputs[0, pos - n : pos] if self.inputs.shape[0] == 1 else self.inputs[:, pos - n : pos].sum(axis=0)

    def grow(self, nfft: int) -> None:
        """Move every applied spectrum to a larger FFT size: the same responses, zero-padded.

        Parameters
        ----------
        nfft : int
            The new FFT size, samples, larger than :attr:`nfft` and at most :data:`HISTORY`.
        """
        if self.nfft:
            self.spectra = sfft.rfft(sfft.irfft(self.spectra, n=self.nfft, axis=-1), n=nfft, axis=-1).astype(np.complex64)
        else:
            self.spectra = np.zeros((self.spectra.shape[0], 2, nfft // 2 + 1), np.complex64)
        self.nfft = nfft

    def update(self, sources: list, paths, schedule, pose: tuple, blocks: int, n: int) -> list:
        """Bring every source's response up to date for the next ``n`` samples.

        Parameters
        ----------
        sources : list of acoustic_sim.acoustics.render_source.Source
            The sources, in row order (at least one).
        paths : acoustic_sim.acoustics.image_paths.PathResponses
            Their paths' geometry and spectra.
        schedule : acoustic_sim.acoustics.image_paths.ReflectionSchedule
            When reflections are due.
        pose : tuple
            ``(head, rot, head_position, head_rotation)``: the head centre (m, room frame)
            as a tuple and an array (3,), the head-to-room rotation as a row-major tuple and
            an array (3, 3).
        blocks : int
            Blocks rendered so far, >= 0.
        n : int
            Samples of the block, 1 to the renderer's ``max_block``.

        Returns
        -------
        list of (int, numpy.ndarray)
            (row, new spectrum (2, nfft // 2 + 1)) of each changed response, for
            :meth:`filter`; a new source's first response is applied at once instead.

        Raises
        ------
        ConfigError
            A source or image inside the head, or responses longer than the history.
        """
        head, rot, head_position, head_rotation = pose
        geometry = [paths.direct(src, head, rot) for src in sources]
        due = [schedule.due(src.reflection_pose, head, rot, tuple(src.position.tolist()), blocks) for src in sources]
        reflections = [paths.reflections(src, head, head_position, head_rotation) if d else src.reflections for src, d in zip(sources, due)]
        length = max(max(g[-1], r[-1], s.tail_head.shape[1] if s.tail_head is not None else 0) for g, r, s in zip(geometry, reflections, sources))
        nfft = max(self.nfft, fft_size(length + n - 1))
        if nfft > HISTORY:
            raise ConfigError(
                f"the sources' early responses are {length} samples long, more than the renderer streams "
                f"({HISTORY - n}); lower the room's ism_order"
            )
        if nfft != self.nfft:
            self.grow(nfft)
            for src in sources:
                src.direct_key, src.direct, src.reflected = None, None, None
        changed = []
        for src, g, r, d in zip(sources, geometry, reflections, due):
            new = self._update_response(src, paths, g, r, (head, rot, tuple(src.position.tolist()), blocks) if d else None)
            if new is not None:
                changed.append((src.row, new))
        return changed

    def _update_response(self, src, paths, direct: tuple, reflections: tuple, pose: tuple | None) -> np.ndarray | None:
        """Bring the source's direct and reflection spectra up to date (``pose``: the
        reflections' update, if due); returns its new response spectrum (2, F) if it
        changed, else None (a new source's first response is applied at once, without a
        cross-fade)."""
        nfft = self.nfft
        changed = False
        if direct[0] != src.direct_key:
            src.direct = paths.direct_spectrum(direct[0], nfft)
            src.direct_key = direct[0]
            changed = True
        if pose is not None:
            src.reflection_pose = pose
        if src.reflected is None or reflections[-2] != src.reflections[-2]:
            src.reflected = paths.reflection_spectrum(src, reflections, nfft)
            src.reflections = reflections
            changed = True
        if not changed:
            return None
        new = src.direct + src.reflected
        if src.fresh:
            self.spectra[src.row] = new
            src.fresh = False
            return None
        return new

    def input_spectrum(self) -> np.ndarray:
        """rFFT of every row's last ``nfft`` input samples.

        Returns
        -------
        numpy.ndarray, shape (S, nfft // 2 + 1), complex64
        """
        return rfft(self.inputs[:, self.pos - self.nfft : self.pos])

    def filter(self, spec: np.ndarray | None, changed: list, late: np.ndarray | None, n: int,
               ramp: Callable[[int], np.ndarray]) -> np.ndarray:
        """The next ``n`` output samples, applying (and cross-fading to) the responses.

        Parameters
        ----------
        spec : numpy.ndarray or None
            :meth:`input_spectrum`, None when there are no sources.
        changed : list of (int, numpy.ndarray)
            (row, new spectrum (2, nfft // 2 + 1)) of each response that changed; each
            becomes the applied one.
        late : numpy.ndarray or None
            A spectrum (2, nfft // 2 + 1) added before the inverse FFT (the late bus).
        n : int
            Samples, 1 to ``nfft``.
        ramp : callable
            ``ramp(n)``: the weight (n,) of the new responses over the block, 0 to 1.

        Returns
        -------
        numpy.ndarray, shape (2, n), float32
            Pressure at the ears, Pa.
        """
        nfft = self.nfft
        if spec is not None:
            held = self.spectra
            y_old = spec[0] * held[0] if spec.shape[0] == 1 else (spec[:, None, :] * held).sum(axis=0)
            if late is not None:
                y_old += late
        else:
            y_old = late
        if y_old is None:
            return np.zeros((2, n), np.float32)
        if not changed:
            return irfft(y_old, nfft)[:, nfft - n :]
        # Old response over the whole block plus the ramped change: one inverse FFT of both.
        both = np.empty((2,) + y_old.shape, np.complex64)
        both[0] = y_old
        row, new = changed[0]
        np.multiply(spec[row], new - held[row], out=both[1])
        held[row] = new
        for row, new in changed[1:]:
            both[1] += spec[row] * (new - held[row])
            held[row] = new
        y = irfft(both, nfft)[:, :, nfft - n :]
        return y[0] + ramp(n) * y[1]
