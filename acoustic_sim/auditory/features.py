"""Features of the two ear spectra: the paper's ILD/IPD per bin and the log-mel spectrogram.

ILD and IPD (the paper's equations, section "Human Mimetic Sound Source Direction
Estimation")::

    X^_{l,r}(w) = X_{l,r}(w) / sqrt(|X_l(w)|^2 + |X_r(w)|^2)
    ILD(w)      = log|X^_l(w)| - log|X^_r(w)|            (natural log)
    IPD(w)      = (Re, Im of X^_l/|X^_l|,  Re, Im of X^_r/|X^_r|)

which gives a 5-number input per bin, in that order: ``[ILD, cos l, sin l, cos r, sin r]``.
Silence is valid input: a bin where an ear's magnitude is below :data:`TINY` is treated as
having magnitude :data:`TINY` and phase 0, so ILD stays finite (at most
``log(max / TINY)``) and the phasor is (1, 0).

Log-mel (section "Binaural Environmental Sound Detection"): 128 mel bands of the power
spectrum, the last 25 frames, "normalized to use relative intensity": each 25 x 128 patch
is expressed in dB relative to its own maximum, floored at -:data:`MEL_RANGE_DB` and scaled
to [-1, 0] (0 = the loudest cell). Level changes (distance) therefore do not change the
input, as the paper intends.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

TINY = 1e-12
"""Magnitude floor (full-scale units) that keeps logs and phasors finite on silence."""

N_MELS = 128
"""Mel bands per ear (the paper)."""

MEL_FRAMES = 25
"""Frames in one mel spectrogram (the paper): 0.4 s at 62.5 Hz."""

MEL_FMIN_HZ = 50.0
MEL_FMAX_HZ = 16000.0
"""Mel band edges: the microphone is flat from 100 Hz to 10 kHz and the six classes have
little energy above 16 kHz."""

MEL_RANGE_DB = 80.0
"""Dynamic range of the normalised log-mel input (dB below the patch maximum)."""


def ild_ipd(left, right) -> np.ndarray:
    """The paper's 5-number ILD/IPD input for each bin.

    Parameters
    ----------
    left, right : array_like of complex, same shape (...)
        Spectra X_l, X_r (any bins, any leading shape).

    Returns
    -------
    numpy.ndarray
        float32, shape (..., 5): ``[ILD, Re, Im of the left unit phasor, Re, Im of the right]``.
    """
    xl = np.asarray(left)
    xr = np.asarray(right)
    if xl.shape != xr.shape:
        raise ConfigError(f"left and right spectra must have the same shape, got {xl.shape} and {xr.shape}")
    al = np.abs(xl)
    ar = np.abs(xr)
    if not (np.all(np.isfinite(al)) and np.all(np.isfinite(ar))):
        raise ConfigError("spectra contain NaN or inf")
    # The common normalisation sqrt(|X_l|^2 + |X_r|^2) cancels in ILD and in the unit
    # phasors; it is written out so the code reads like the paper.
    norm = np.sqrt(al**2 + ar**2)
    norm = np.where(norm > 0, norm, 1.0)
    ml = np.maximum(al / norm, TINY / norm)
    mr = np.maximum(ar / norm, TINY / norm)
    ild = np.log(ml) - np.log(mr)
    out = np.empty(xl.shape + (5,), np.float32)
    out[..., 0] = ild
    for j, (x, a) in enumerate(((xl, al), (xr, ar))):
        ok = a > TINY
        safe = np.where(ok, a, 1.0)
        out[..., 1 + 2 * j] = np.where(ok, x.real / safe, 1.0)
        out[..., 2 + 2 * j] = np.where(ok, x.imag / safe, 0.0)
    return out


def hz_to_mel(f):
    """HTK mel scale: 2595 log10(1 + f / 700)."""
    return 2595.0 * np.log10(1.0 + np.asarray(f, float) / 700.0)


def mel_to_hz(m):
    return 700.0 * (10.0 ** (np.asarray(m, float) / 2595.0) - 1.0)


@lru_cache(maxsize=8)
def mel_filterbank(n_fft: int = 2048, sample_rate: int = SAMPLE_RATE, n_mels: int = N_MELS,
                   fmin: float = MEL_FMIN_HZ, fmax: float = MEL_FMAX_HZ) -> np.ndarray:
    """Triangular mel filters, float32 (n_mels, n_fft // 2 + 1), each summing to 1.

    Written here rather than taken from a library because none of the project's
    dependencies has one (librosa and torchaudio are not installed for this alone). Bands
    narrower than an FFT bin (the lowest ones) take the bin nearest their centre, so no
    band is empty.
    """
    if not 0 <= fmin < fmax <= sample_rate / 2:
        raise ConfigError(f"mel band edges must satisfy 0 <= fmin < fmax <= {sample_rate / 2}, got {fmin}, {fmax}")
    freqs = np.fft.rfftfreq(n_fft, 1.0 / sample_rate)
    edges = mel_to_hz(np.linspace(hz_to_mel(fmin), hz_to_mel(fmax), n_mels + 2))
    lo, centre, hi = edges[:-2], edges[1:-1], edges[2:]
    up = (freqs[None, :] - lo[:, None]) / (centre - lo)[:, None]
    down = (hi[:, None] - freqs[None, :]) / (hi - centre)[:, None]
    bank = np.clip(np.minimum(up, down), 0.0, None)
    empty = bank.sum(axis=1) == 0
    bank[empty, np.rint(centre[empty] * n_fft / sample_rate).astype(int)] = 1.0
    return (bank / bank.sum(axis=1, keepdims=True)).astype(np.float32)


def mel_power(spectra, *, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Mel-band power of spectra (..., n_bins) -> float32 (..., N_MELS)."""
    x = np.asarray(spectra)
    n_fft = 2 * (x.shape[-1] - 1)
    power = (x.real.astype(np.float32) ** 2 + x.imag.astype(np.float32) ** 2)
    return power @ mel_filterbank(n_fft, sample_rate).T


def normalize_log_mel(mel_power_frames) -> np.ndarray:
    """Relative-intensity log-mel of one or more patches (..., T, N_MELS) -> float32 in [-1, 0].

    Each patch (the last two axes) is put in dB relative to its own maximum, floored at
    -MEL_RANGE_DB and divided by MEL_RANGE_DB. An all-silent patch gives all -1.
    """
    p = np.asarray(mel_power_frames, np.float32)
    return _relative_log_mel(_mel_db(p), p)


def _mel_db(p: np.ndarray) -> np.ndarray:
    """dB of float32 mel power, elementwise (so a patch's rows can be converted once each)."""
    return 10.0 * np.log10(np.maximum(p, TINY**2))


def _relative_log_mel(db: np.ndarray, p: np.ndarray) -> np.ndarray:
    """:func:`normalize_log_mel` of patches given their dB (:func:`_mel_db`) and power."""
    top = db.max(axis=(-2, -1), keepdims=True)
    rel = np.clip(db - top, -MEL_RANGE_DB, 0.0) / MEL_RANGE_DB
    silent = np.all(p <= TINY**2, axis=(-2, -1), keepdims=True)
    return np.where(silent, -1.0, rel).astype(np.float32)


def ear_volume(spectra) -> np.ndarray:
    """Volume V of each ear for the paper's binaural fusion: mean power over bins.

    spectra (..., n_bins) complex -> float64 (...). Any positive measure of loudness works in
    p = (V_l p_l + V_r p_r) / (V_l + V_r); mean spectral power is what the board has at hand.
    """
    x = np.asarray(spectra)
    return np.mean(x.real.astype(np.float64) ** 2 + x.imag.astype(np.float64) ** 2, axis=-1)


class MelHistory:
    """The last :data:`MEL_FRAMES` mel-power frames of both ears, for the streaming pipeline.

    ``push(spectra)`` takes one frame (2, n_bins); ``patch()`` returns the normalised log-mel
    input (2, MEL_FRAMES, N_MELS) float32, the oldest frame first (frames before the start
    are silent).
    """

    def __init__(self, *, frames: int = MEL_FRAMES, sample_rate: int = SAMPLE_RATE) -> None:
        self.sample_rate = sample_rate
        self.power = np.zeros((2, frames, N_MELS), np.float32)
        self._db = _mel_db(self.power)  # each frame's dB, converted once when it arrives

    def reset(self) -> None:
        self.power[:] = 0.0
        self._db = _mel_db(self.power)

    def push(self, spectra) -> None:
        x = np.asarray(spectra)
        if x.ndim != 2 or x.shape[0] != 2:
            raise ConfigError(f"one frame of spectra must have shape (2, n_bins), got {x.shape}")
        self.power = np.roll(self.power, -1, axis=1)
        self.power[:, -1] = mel_power(x, sample_rate=self.sample_rate)
        self._db = np.roll(self._db, -1, axis=1)
        self._db[:, -1] = _mel_db(self.power[:, -1])

    def patch(self) -> np.ndarray:
        """``normalize_log_mel(self.power)``, from the stored dB."""
        return _relative_log_mel(self._db, self.power)


def log_mel_patches(spectra, *, frames: int = MEL_FRAMES, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Normalised log-mel patches ending at every frame of a recording.

    spectra (K, 2, n_bins) -> float32 (K, 2, frames, N_MELS): patch k holds frames
    k - frames + 1 .. k (silence before the first frame), the same as :class:`MelHistory`.
    """
    x = np.asarray(spectra)
    if x.ndim != 3 or x.shape[1] != 2:
        raise ConfigError(f"spectra must have shape (K, 2, n_bins), got {x.shape}")
    p = mel_power(x, sample_rate=sample_rate)  # (K, 2, M)
    padded = np.concatenate([np.zeros((frames - 1,) + p.shape[1:], np.float32), p], axis=0)
    win = np.lib.stride_tricks.sliding_window_view(padded, frames, axis=0)  # (K, 2, M, frames)
    return normalize_log_mel(win.transpose(0, 1, 3, 2))
