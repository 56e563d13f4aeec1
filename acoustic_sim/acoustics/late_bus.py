"""The renderer's late-reverb bus: the room's tail, shared by all sources.

A source's diffuse tail (:func:`~acoustic_sim.acoustics.room.late_tail`) depends on the
source only until the images it rendered have all arrived (its fill is complete); after
that the statistical late energy at time t after emission does not depend on where the
source is. So the renderer convolves the sum of all sources' signals with one room tail
from :data:`BUS_START` samples on (:func:`room_tail`, streamed by a
:class:`~acoustic_sim.acoustics.convolution.FrameConvolver`), and each source keeps its
own tail only up to there (:func:`tail_head`), ending with a short power-complementary
cross-fade into the bus and minus the bus's own response before that point, so that the
tail each source gets is exactly its own head followed by the room's tail.
"""

from __future__ import annotations

import copy
import math
from typing import Callable

import numpy as np

from acoustic_sim.acoustics.convolution import FrameConvolver, irfft
from acoustic_sim.acoustics.room import ImageSources, Room, late_tail, tail_complete_sample
from acoustic_sim.frames import FRAME_RATE

BUS_START = 1024
"""Where the late-reverb bus starts (samples into the response): before any source's tail
fill completes in small rooms (the car cabin: 25-28 ms), and after a control block (the
bus's partitions are control blocks; a higher sample rate starts it after its longest)."""

TAIL_SPLICE = 64
"""Length (samples) of the cross-fade from a source's own tail head into the bus."""


def bus_start(sample_rate: int) -> int:
    """Where the bus starts at ``sample_rate`` (Hz, > 0): :data:`BUS_START`, or the power of
    two at or after the longest control block if that is later; in samples."""
    longest_block = math.ceil(sample_rate / FRAME_RATE)
    return max(BUS_START, 1 << (longest_block - 1).bit_length())


def room_tail(room: Room, head_position, tables, rng: np.random.Generator, sample_rate: int, start: int) -> np.ndarray:
    """The room's late tail, zero before ``start``: the bus's filter.

    Parameters
    ----------
    room : acoustic_sim.acoustics.room.Room
        A room that is not anechoic.
    head_position : array_like, shape (3,)
        Head centre, m (room frame).
    tables : acoustic_sim.acoustics.hrtf_tables.HRTFTables
        The HRTF's tables (their diffuse-field power and coherence shape the tail).
    rng : numpy.random.Generator
        Draws the tail's noise.
    sample_rate : int
        Hz, > 0.
    start : int
        First sample of the bus (:func:`bus_start`), >= 0.

    Returns
    -------
    numpy.ndarray, shape (2, L), float64
        In the renderer's units (pressure at the ear per unit pressure at 1 m).
    """
    power, coherence = tables.diffuse_field()
    tail = late_tail(room, None, head_position, diffuse_power=power, coherence=coherence, rng=rng, sample_rate=sample_rate)
    tail[:, :start] = 0.0
    return tail


def tail_head(
    room: Room, images: ImageSources, head_position, bus: np.ndarray, tables, rng: np.random.Generator,
    sample_rate: int, start: int,
) -> np.ndarray:
    """A source's own tail up to where the bus takes over, minus the bus's response there.

    Head plus bus is then: the source's own tail until its fill is complete (and at least
    until the bus starts), a power-complementary cross-fade of :data:`TAIL_SPLICE` samples,
    then the room's tail on the bus.

    Parameters
    ----------
    room : acoustic_sim.acoustics.room.Room
        A room that is not anechoic.
    images : acoustic_sim.acoustics.room.ImageSources
        The source's rendered image sources.
    head_position : array_like, shape (3,)
        Head centre, m (room frame).
    bus : numpy.ndarray, shape (2, L)
        The bus's filter (:func:`room_tail`).
    tables : acoustic_sim.acoustics.hrtf_tables.HRTFTables
        The HRTF's tables.
    rng : numpy.random.Generator
        Draws the tail's noise.
    sample_rate : int
        Hz, > 0.
    start : int
        First sample of the bus, >= 0.

    Returns
    -------
    numpy.ndarray, shape (2, T), float64
        T = min(splice + TAIL_SPLICE, L), the splice being where the fill completes or
        ``start``, whichever is later.
    """
    power, coherence = tables.diffuse_field()
    complete = tail_complete_sample(room, images, head_position, sample_rate=sample_rate)
    splice = max(complete, start)
    end = min(splice + TAIL_SPLICE, bus.shape[1])
    own = late_tail(room, images, head_position, diffuse_power=power, coherence=coherence, rng=rng, sample_rate=sample_rate, n_samples=end)
    own = np.pad(own, ((0, 0), (0, end - own.shape[1])))
    fade = np.ones(end)
    w = np.sin(0.5 * np.pi * (np.arange(end - splice) + 0.5) / TAIL_SPLICE)  # bus fade-in
    fade[splice:] = np.sqrt(1.0 - w**2)
    into_bus = np.zeros(end)
    into_bus[splice:] = w
    return own * fade + bus[:, :end] * (into_bus - 1.0)


class LateBus:
    """One renderer's late-reverb bus: the room's tail (:func:`room_tail`, made on first
    use), streamed by a :class:`FrameConvolver` whose partitions are the control blocks.

    Parameters
    ----------
    room : acoustic_sim.acoustics.room.Room
        The room (the bus is only made for one that is not anechoic).
    tables : acoustic_sim.acoustics.hrtf_tables.HRTFTables
        The HRTF's tables.
    rng : numpy.random.Generator
        Draws the tails' noise (the renderer's).
    sample_rate : int
        Hz, > 0.
    """

    def __init__(self, room: Room, tables, rng: np.random.Generator, sample_rate: int) -> None:
        self.room, self.tables, self.rng, self.sample_rate = room, tables, rng, sample_rate
        self.start = bus_start(sample_rate)
        self.filter: np.ndarray | None = None  # (2, L), zero before start
        self.convolver: FrameConvolver | None = None
        self._block = None  # the bus's output for the current control block, when rendered in pieces

    def restarted(self) -> "LateBus":
        """A bus with the same filter and no input yet (a fresh stream's).

        Returns
        -------
        LateBus
        """
        bus = copy.copy(self)
        bus.convolver = FrameConvolver(self.filter) if self.filter is not None else None
        bus._block = None
        return bus

    def ensure(self, head_position, nfft: int) -> np.ndarray:
        """The bus's filter, made on the first call.

        Parameters
        ----------
        head_position : array_like, shape (3,)
            Head centre, m (room frame), at the first call.
        nfft : int
            The early overlap-save's FFT size, samples (0: none yet).

        Returns
        -------
        numpy.ndarray, shape (2, L), float64
        """
        if self.filter is None:
            self.filter = room_tail(self.room, head_position, self.tables, self.rng, self.sample_rate, self.start)
            self.convolver = FrameConvolver(self.filter)
            if nfft:
                self.convolver.set_fft_size(nfft)
        return self.filter

    def source_tail(self, images: ImageSources, head_position, nfft: int) -> np.ndarray:
        """A source's :func:`tail_head` against this bus (made first if need be).

        Parameters
        ----------
        images : acoustic_sim.acoustics.room.ImageSources
            The source's rendered image sources.
        head_position : array_like, shape (3,)
            Head centre, m (room frame).
        nfft : int
            The early overlap-save's FFT size, samples (0: none yet).

        Returns
        -------
        numpy.ndarray, shape (2, T), float64
        """
        bus = self.ensure(head_position, nfft)
        return tail_head(self.room, images, head_position, bus, self.tables, self.rng, self.sample_rate, self.start)

    def late_spectrum(self, nfft: int, frame_len: int, frame_start: bool, frame_end: bool) -> np.ndarray | None:
        """The bus's spectrum to add before the early inverse FFT.

        For the first piece of a control block rendered in pieces, the bus's block is
        rendered on its own instead (and :meth:`advance` adds it).

        Parameters
        ----------
        nfft : int
            The early overlap-save's FFT size, samples (0: nothing streamed yet).
        frame_len : int
            Length of the current control block, samples (>= 1).
        frame_start, frame_end : bool
            Whether the piece starts, and ends, the control block.

        Returns
        -------
        numpy.ndarray, shape (2, nfft // 2 + 1), complex64, or None
        """
        if self.convolver is None or not nfft:
            return None
        late = self.convolver.output(frame_len) if frame_start else None
        if late is not None and not frame_end:
            self._block = irfft(late, nfft)[:, nfft - frame_len :]
            late = None
        return late

    def advance(self, out: np.ndarray, recent: Callable[[int], np.ndarray], spec: np.ndarray | None, offset: int,
                frame_len: int, frame_start: bool, frame_end: bool, nfft: int) -> None:
        """Finish a piece: add the bus's own block, feed the bus, push its window at the end.

        Parameters
        ----------
        out : numpy.ndarray, shape (2, n)
            The piece's pressure (Pa); the bus's block is added in place when the control
            block is rendered in pieces.
        recent : callable
            ``recent(n)``: the sources' summed input (Pa at 1 m) of the piece, shape (n,).
        spec : numpy.ndarray, shape (S, nfft // 2 + 1), or None
            The early overlap-save's input spectrum (None without sources).
        offset : int
            The piece's first sample within the control block, 0 to ``frame_len`` - 1.
        frame_len : int
            Length of the control block, samples.
        frame_start, frame_end : bool
            Whether the piece starts, and ends, the control block.
        nfft : int
            The early overlap-save's FFT size, samples.
        """
        if self.convolver is None or not nfft:
            return
        n = out.shape[1]
        if not (frame_start and frame_end) and self._block is not None:
            out += self._block[:, offset : offset + n]
        self.convolver.feed(recent(n))
        if frame_end:
            if spec is None:
                spec = np.zeros((1, nfft // 2 + 1), np.complex64)
            self.convolver.push(spec[0] if spec.shape[0] == 1 else spec.sum(axis=0), frame_len)
            self._block = None
