"""The precedence effect for the streaming pipeline: spectra of the first wavefront.

In a small reverberant space an ear frame (2048 samples, 46 ms) holds a sound's direct path
together with its reflections, and in the car cabin the reflections win (the side window
and the floor return almost as much energy as the direct path, within 1-2 ms of it), so the
frame's interaural cues are the mixture's and SSDENet, trained on free-field HRTFs, places
the sound near the median plane or on the wrong side. Listeners localize such sounds by
their first wavefront; :class:`FirstWavefront` does that on the sample clock.

- **Onsets**: the energy of 0.5 ms blocks, high-passed at 1 kHz, rising ``ratio`` times
  above the median of the preceding 1-10 ms. At each onset it returns the spectrum of a
  window from 0.25 ms before to 1.5 ms after it (Tukey-tapered, zero-padded to the front
  end's 2048 points, so its bins are the front end's); the pipeline computes the ILD/IPD
  features from it in place of the frame's, at the bins above :attr:`FirstWavefront.min_hz`
  (two periods in the window, 1.1 kHz). Frames without an onset give no direction evidence.
- **Which sound an onset is** (``added_ms``): the energy the onset *added*, the power
  spectrum of the ``added_ms`` after it minus that of the ``added_ms`` before it
  (:meth:`FirstWavefront.take_added`); the sounds already playing cancel.
- **A rising onset** (``align_lag_ms``, ``rise_ratio``; off by default): on a ramp the far
  ear, later by the interaural delay, is further down the ramp, which overstates the ILD;
  the far ear's magnitude can be taken from a window delayed by the interaural lag.
- **More looks at a rising onset** (``windows``, ``hop_ms``): a rising onset can get several
  windows, ``hop_ms`` apart, whose maps the pipeline averages per bin; a click keeps one.

The measurements behind each of these (ParkingBrake and ReverseAlarm episodes, paper and
fast models) are in docs/notes/precedence.md. Hand-written because no library in the
project detects onsets on a streaming sample clock (scipy has the filters, which are used).
"""

from __future__ import annotations

import numpy as np
from scipy import signal as sp_signal

from acoustic_sim.auditory.frontend import N_FFT
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE


ENVELOPE_MARGIN = 32
"""Samples (0.7 ms) kept beyond an onset's window (and the searched lags) for its Hilbert envelopes."""


class FirstWavefront:
    """Streaming onset detector that keeps the spectrum of each onset's first wavefront.

    Parameters
    ----------
    sample_rate : int
        Hz.
    highpass_hz : float
        Onsets are detected above this frequency (2nd-order Butterworth), where the
        head shadows and the reflections' delays are long against the period.
    block_ms : float
        Energy blocks (both ears summed), ms.
    baseline_ms : tuple of 2 float
        The baseline is the median block energy from ``baseline_ms[1]`` to
        ``baseline_ms[0]`` before a block.
    ratio : float
        A block is an onset when its energy exceeds ``ratio`` times the baseline and the
        previous block's did not (> 1).
    refractory_ms : float
        No new onset this soon after the last one.
    window_ms : tuple of 2 float
        The first-wavefront window: from ``window_ms[0]`` before the onset block to
        ``window_ms[1]`` after its start.
    n_fft : int
        FFT size of the window's spectrum (the front end's, so the bins agree).
    added_ms : float, optional
        Length (ms) of the segments before and after an onset whose power difference is the
        energy it added (:meth:`take_added`, module docstring); None (default): not kept.
    align_lag_ms : float or None
        Largest interaural lag (ms) searched when aligning a rising onset's ears (module
        docstring; 0.8 covers the head's 0.7 ms); None (default): never aligned. With it, an
        onset's window is ready ``align_lag_ms`` plus :data:`ENVELOPE_MARGIN` later.
    rise_ratio : float
        An onset is rising when the second half of its window holds at least this many
        times the energy of the first half (> 0; default 2): only rising onsets are
        aligned, and only they get more than one window.
    windows : int
        Windows taken at a rising onset (>= 1; default 1): the first wavefront's and
        ``windows - 1`` more, each ``hop_ms`` later (module docstring). With more than one,
        :meth:`take_onset` returns their spectra stacked (k, 2, n_fft // 2 + 1).
    hop_ms : float
        Spacing (ms) of those windows (> 0; default 1).
    """

    def __init__(self, *, sample_rate: int = SAMPLE_RATE, highpass_hz: float = 1000.0, block_ms: float = 0.5,
                 baseline_ms: tuple[float, float] = (1.0, 10.0), ratio: float = 8.0, refractory_ms: float = 15.0,
                 window_ms: tuple[float, float] = (0.25, 1.5), n_fft: int = N_FFT,
                 added_ms: float | None = None, align_lag_ms: float | None = None,
                 rise_ratio: float = 2.0, windows: int = 1, hop_ms: float = 1.0) -> None:
        if not 0.0 < highpass_hz < sample_rate / 2:
            raise ConfigError(f"highpass_hz must be in (0, {sample_rate / 2}), got {highpass_hz}")
        if not (np.isfinite(ratio) and ratio > 1.0):
            raise ConfigError(f"ratio must be > 1, got {ratio}")
        lo, hi = baseline_ms
        if not 0.0 <= lo < hi:
            raise ConfigError(f"baseline_ms must be (near, far) with 0 <= near < far, got {baseline_ms}")
        pre, post = window_ms
        if not (pre >= 0.0 and post > 0.0):
            raise ConfigError(f"window_ms must be (before >= 0, after > 0), got {window_ms}")
        self.sample_rate = int(sample_rate)
        self.block = max(1, round(block_ms * 1e-3 * sample_rate))
        self.near = max(1, round(lo * 1e-3 * sample_rate / self.block))
        self.far = max(self.near + 1, round(hi * 1e-3 * sample_rate / self.block))
        self.ratio = float(ratio)
        self.refractory = max(1, round(refractory_ms * 1e-3 * sample_rate / self.block))
        self.pre = round(pre * 1e-3 * sample_rate)
        self.post = round(post * 1e-3 * sample_rate)
        if self.pre + self.post > n_fft:
            raise ConfigError(f"window_ms {window_ms} is longer than n_fft ({n_fft} samples)")
        self.n_fft = int(n_fft)
        self.added = None
        if added_ms is not None:
            if not (np.isfinite(added_ms) and added_ms > 0):
                raise ConfigError(f"added_ms must be > 0 ms, got {added_ms}")
            self.added = round(added_ms * 1e-3 * sample_rate)
            if self.added > n_fft:
                raise ConfigError(f"added_ms {added_ms} is longer than n_fft ({n_fft} samples)")
            self._hann = sp_signal.windows.hann(self.added, sym=False)
        self.lag = 0
        if align_lag_ms is not None:
            if not (np.isfinite(align_lag_ms) and align_lag_ms > 0):
                raise ConfigError(f"align_lag_ms must be > 0 ms or None, got {align_lag_ms}")
            self.lag = max(1, round(align_lag_ms * 1e-3 * sample_rate))
        if not (np.isfinite(rise_ratio) and rise_ratio > 0):
            raise ConfigError(f"rise_ratio must be > 0, got {rise_ratio}")
        self.rise_ratio = float(rise_ratio)
        if not (isinstance(windows, (int, np.integer)) and windows >= 1):
            raise ConfigError(f"windows must be an integer >= 1, got {windows!r}")
        if not (np.isfinite(hop_ms) and hop_ms > 0):
            raise ConfigError(f"hop_ms must be > 0 ms, got {hop_ms}")
        self.windows = int(windows)
        self.hop = max(1, round(hop_ms * 1e-3 * sample_rate))
        self._extra = (self.windows - 1) * self.hop  # samples the later windows reach beyond the first
        self._rises = bool(self.lag) or self.windows > 1  # whether onsets are tested for a rise
        # Samples beyond the searched lags on either side, so that the Hilbert envelope's
        # edge effects stay outside the compared stretch.
        self._margin = self.lag + (ENVELOPE_MARGIN if self._rises else 0)
        self.ready_after = self.post + self._margin
        """Samples after an onset that must have been pushed before its window is taken (a
        rising onset with more ``windows`` waits ``(windows - 1) * hop_ms`` more)."""
        self.min_hz = 2.0 * sample_rate / (self.pre + self.post)
        """Lowest frequency (Hz) with two periods in the window; below it the window's
        spectrum is the taper's, not the sound's (the pipeline uses the frame there)."""
        self.taper = sp_signal.windows.tukey(self.pre + self.post, 0.3)
        self._sos = sp_signal.butter(2, highpass_hz, btype="high", fs=sample_rate, output="sos")
        self._keep = self.pre + self.post + self.block + 2 * self._margin + self._extra  # raw samples kept
        self.reset()

    def reset(self) -> None:
        """Back to sample 0, no history."""
        self._zi = np.zeros((self._sos.shape[0], 2, 2))  # (sections, ears, 2)
        self.sample = 0  # samples pushed so far
        self._partial = np.zeros(0)  # high-passed energy of the samples of an unfinished block
        self._energy = np.full(self.far, np.inf)  # the last ``far`` block energies (inf: before the start)
        self._above = False  # whether the last block was above its threshold
        self._blocks = 0  # whole blocks seen
        self._last_onset = -(10**9)  # block index of the last onset
        self._audio = np.zeros((2, 0))  # the newest raw samples
        self._hp = np.zeros((2, 0))  # the same samples high-passed
        self._audio_start = 0  # sample index of self._audio[:, 0]
        self.pending: list[tuple[int, float]] = []  # (onset sample, block energy), windows not yet taken
        self.awaiting: list[int] = []  # taken onsets whose added energy is not yet handed over

    def push(self, block: np.ndarray) -> None:
        """Append a (2, n) block of ear samples (the pipeline's, already checked)."""
        x = np.asarray(block, dtype=np.float64)
        n = x.shape[1]
        if n == 0:
            return
        y, self._zi = sp_signal.sosfilt(self._sos, x, axis=-1, zi=self._zi)
        e = np.concatenate([self._partial, (y**2).sum(axis=0)])
        whole = e.size // self.block
        first = self.sample - self._partial.size  # sample index of e[0]
        self._partial = e[whole * self.block:]
        blocks = e[: whole * self.block].reshape(whole, self.block).sum(axis=1)
        if whole:
            energy = np.concatenate([self._energy, blocks])
            # Block j's baseline: the median of blocks j - far .. j - near (inf before the start).
            windows = np.lib.stride_tricks.sliding_window_view(energy, self.far - self.near + 1)[:whole]
            above = blocks > self.ratio * _row_medians(windows)
            rising = above & ~np.concatenate([[self._above], above[:-1]])
            for j in np.flatnonzero(rising):
                b = self._blocks + int(j)
                if b - self._last_onset > self.refractory:
                    self.pending.append((first + int(j) * self.block, float(blocks[j])))
                    self._last_onset = b
            self._above = bool(above[-1])
            self._energy = energy[-self.far:]
            self._blocks += whole
        audio = np.concatenate([self._audio, x], axis=1)
        hp = np.concatenate([self._hp, y], axis=1) if self._rises else self._hp
        self.sample += n
        oldest = min([s - self.pre - self._margin for s, _ in self.pending] + [s - self.added for s in self.awaiting]
                     + [self.sample - self._keep])
        cut = max(0, oldest - self._audio_start)
        self._audio = audio[:, cut:]
        if self._rises:
            self._hp = hp[:, cut:]
        self._audio_start += cut

    def take(self, end_sample: int) -> np.ndarray | None:
        """The spectrum (2, n_fft // 2 + 1) of the strongest onset whose window ends by
        ``end_sample`` (with ``windows`` > 1 its windows' spectra, (k, 2, n_fft // 2 + 1)),
        or None; every onset up to there is consumed (:meth:`take_onset`)."""
        taken = self.take_onset(end_sample)
        return None if taken is None else taken[1]

    def take_onset(self, end_sample: int) -> tuple[int, np.ndarray] | None:
        """(onset sample, spectrum (2, n_fft // 2 + 1)) of the strongest onset whose windows
        end by ``end_sample``, or None; every such onset is consumed (a rising one whose
        later windows are not complete yet waits), and with ``added_ms`` the one returned
        awaits :meth:`take_added`. With ``windows`` > 1 the spectra of its windows,
        (k, 2, n_fft // 2 + 1): k = ``windows`` for a rising onset, else 1."""
        rises: dict[int, bool] = {}
        ready = []
        for s, e in self.pending:
            if s + self.ready_after > end_sample:
                continue
            if self._rises:
                rises[s] = self.rising(s)
                if rises[s] and self.windows > 1 and s + self.ready_after + self._extra > end_sample:
                    continue  # its later windows are not complete yet
            ready.append((s, e))
        if not ready:
            return None
        taken = {s for s, _ in ready}
        self.pending = [(s, e) for s, e in self.pending if s not in taken]
        s, _ = max(ready, key=lambda item: item[1])
        if self.added is not None:
            self.awaiting.append(s)
        n = self.pre + self.post
        rising = rises.get(s, False)
        lag = self._lag(s) if rising and self.lag else 0
        spectra = []
        for j in range(self.windows if rising else 1):
            start = s - self.pre + j * self.hop
            spectrum = np.fft.rfft(self._segment(start, n) * self.taper, n=self.n_fft, axis=-1)
            if lag:
                # The far ear's level from its window shifted by the lag, its phase from the common one.
                far = 1 if lag > 0 else 0
                shifted = np.fft.rfft(self._segment(start + abs(lag), n)[far] * self.taper, n=self.n_fft)
                spectrum[far] = np.abs(shifted) * np.exp(1j * np.angle(spectrum[far]))
            spectra.append(spectrum)
        return s, (np.stack(spectra) if self.windows > 1 else spectra[0])

    def _envelopes(self, onset: int, extra: int = 0) -> np.ndarray:
        """Hilbert power envelopes (2, n + extra) of the high-passed ears from the onset's
        window start (needs ``align_lag_ms`` or ``windows`` > 1)."""
        n, m = self.pre + self.post, self._margin
        hp = self._segment(onset - self.pre - m, n + 2 * m, self._hp)
        env = np.abs(sp_signal.hilbert(hp, axis=-1)) ** 2
        return env[:, m: m + n + extra] + 1e-30

    def rising(self, onset: int) -> bool:
        """Whether the onset at sample ``onset`` rises: the second half of its window holds
        at least ``rise_ratio`` times the first half's energy (both ears, high-passed,
        Hilbert envelopes); always False without ``align_lag_ms`` or more ``windows``."""
        if not self._rises:
            return False
        both = self._envelopes(onset).sum(axis=0)
        half = both.size // 2
        return bool(both[half:].sum() >= self.rise_ratio * both[:half].sum())

    def interaural_lag(self, onset: int) -> int:
        """The right ear's lag (samples, + later) behind the left for the onset at sample
        ``onset``: 0 unless the onset is :meth:`rising` and ``align_lag_ms`` is set; else
        the delay (up to ``align_lag_ms``) of the far ear (the one with less energy in the
        window) behind the near one at which their log envelopes differ most steadily over
        the window (weighted by the envelopes' geometric mean). See the module docstring."""
        if not self.lag or not self.rising(onset):
            return 0
        return self._lag(onset)

    def _lag(self, onset: int) -> int:
        n, lag = self.pre + self.post, self.lag
        env = self._envelopes(onset, lag)  # (2, n + lag): the window and the later lags
        common = env[:, :n]
        near = int(common[1].sum() > common[0].sum())
        ref = common[near]
        far = np.lib.stride_tricks.sliding_window_view(env[1 - near], n)  # (lag + 1, n): far[k] = k samples later
        w = np.sqrt(np.sqrt(ref) * np.sqrt(far))
        d = np.log(ref) - np.log(far)
        mean = (w * d).sum(axis=1) / w.sum(axis=1)
        spread = (w * (d - mean[:, None]) ** 2).sum(axis=1) / w.sum(axis=1)
        k = int(np.argmin(spread))
        return k if near == 0 else -k

    def take_added(self, end_sample: int) -> list[tuple[int, np.ndarray]]:
        """(onset sample, added power (n_fft // 2 + 1,)) of each taken onset whose ``added_ms``
        after it end by ``end_sample``: the power spectrum of those samples minus that of the
        ``added_ms`` before the onset (Hann window, both ears summed, clipped at 0)."""
        if self.added is None:
            return []
        out = []
        for s in [s for s in self.awaiting if s + self.added <= end_sample]:
            after = np.fft.rfft(self._segment(s, self.added) * self._hann, n=self.n_fft, axis=-1)
            before = np.fft.rfft(self._segment(s - self.added, self.added) * self._hann, n=self.n_fft, axis=-1)
            power = (after.real**2 + after.imag**2).sum(axis=0) - (before.real**2 + before.imag**2).sum(axis=0)
            out.append((s, np.maximum(power, 0.0)))
        self.awaiting = [s for s in self.awaiting if s + self.added > end_sample]
        return out

    def _segment(self, start: int, n: int, audio: np.ndarray | None = None) -> np.ndarray:
        """Raw samples ``start .. start + n`` (2, n) (of ``audio``, a buffer aligned with the
        raw one: the high-passed samples); zeros before the first sample."""
        a = start - self._audio_start
        seg = np.zeros((2, n))
        lo = max(a, 0)
        part = (self._audio if audio is None else audio)[:, lo : a + n]
        seg[:, lo - a : lo - a + part.shape[1]] = part
        return seg


def _row_medians(w: np.ndarray) -> np.ndarray:
    """``np.median(w, axis=1)``, the same numbers, by partial sorting (five times faster on
    the detector's 32 x 19 windows, where ``np.median``'s overhead dominates)."""
    n = w.shape[1]
    k = n // 2
    if n % 2:
        return np.partition(w, k, axis=1)[:, k]
    part = np.partition(w, (k - 1, k), axis=1)
    return (part[:, k - 1] + part[:, k]) / 2.0


__all__ = ["FirstWavefront"]
