"""The paper's valid bins c_i: which bins of a frame carry a sound worth localising.

A bin is valid when its power is 10 dB above the noise (the paper's rule), within the
detected class's characteristic bins, and, with ``leakage``, above what the Hamming
window's sidelobes of the frame's stronger bins can put there (:data:`LEAKAGE`).
"""

from __future__ import annotations

import functools

import numpy as np

from acoustic_sim.auditory.frontend import leakage_envelope
from acoustic_sim.errors import ConfigError


def bin_mask(spec, n_bins: int, what: str) -> np.ndarray:
    """A bool mask (..., n_bins) from a bool mask or integer bin indices."""
    m = np.asarray(spec)
    if m.dtype == bool:
        if m.shape[-1:] != (n_bins,):
            raise ConfigError(f"{what} mask must have {n_bins} bins on its last axis, got shape {m.shape}")
        return m
    if m.size == 0:
        return np.zeros(n_bins, bool)
    if not np.issubdtype(m.dtype, np.integer) or m.ndim != 1:
        raise ConfigError(f"{what} must be a bool mask over the {n_bins} bins or a 1-D array of bin indices, "
                          f"got dtype {m.dtype}, shape {m.shape}")
    if m.min() < 0 or m.max() >= n_bins:
        raise ConfigError(f"{what} indices must lie in 0..{n_bins - 1}, got {m.min()}..{m.max()}")
    out = np.zeros(n_bins, bool)
    out[m] = True
    return out


def check_spectra(spectra) -> np.ndarray:
    """``spectra`` as an array of shape (..., 2, n_bins) of finite numbers, else a :class:`ConfigError`."""
    x = np.asarray(spectra)
    if x.ndim < 2 or x.shape[-2] != 2:
        raise ConfigError(f"spectra must have shape (..., 2, n_bins) (left, right), got {x.shape}")
    if not np.issubdtype(x.dtype, np.number):
        raise ConfigError(f"spectra must be numbers, got dtype {x.dtype}")
    if not np.all(np.isfinite(x)):
        raise ConfigError("spectra contain NaN or inf")
    return x


def noise_power_spectrum(spectra) -> np.ndarray:
    """Mean power per ear and bin of noise-only frames, for :func:`valid_bins`.

    Parameters
    ----------
    spectra : array_like, complex (K, 2, n_bins) or (2, n_bins)
        Front-end spectra of a recording of the noise alone (e.g. the robot's driving noise).

    Returns
    -------
    numpy.ndarray, float64 (2, n_bins)
        Mean |X|^2 over the frames (full-scale units squared).
    """
    x = check_spectra(spectra)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[0] == 0:
        raise ConfigError(f"noise spectra must have shape (K >= 1, 2, n_bins), got {x.shape}")
    return np.mean(np.abs(x.astype(np.complex128)) ** 2, axis=0)


def valid_bins(spectra, noise_power, factor: float = 10.0, class_bins=None, *, leakage: float = 0.0) -> np.ndarray:
    """The paper's valid bins c_i: power above ``factor`` times the noise, within a class's bins.

    Parameters
    ----------
    spectra : array_like, complex (..., 2, n_bins)
        Front-end spectra (left, right) of one or more frames.
    noise_power : float or array_like broadcastable to (2, n_bins)
        Power spectrum per ear of the noise the threshold refers to (the paper: the robot's
        driving noise; e.g. :func:`noise_power_spectrum`), in the units of ``|X|^2``, >= 0.
    factor : float
        A bin is valid when ``|X_l|^2 + |X_r|^2 > factor * (N_l + N_r)`` (the paper: 10,
        i.e. 10 dB above the noise), > 0.
    class_bins : array_like, optional
        The characteristic bins of the detected sound class (MelCNN): a bool mask over the
        n_bins bins or integer bin indices. Valid bins are intersected with them.
    leakage : float
        0 (the paper's rule alone) or a factor > 0: a bin is valid only when its power also
        exceeds ``leakage`` times the most that the Hamming window's sidelobes of any other
        bin of the frame can put there (:func:`~acoustic_sim.auditory.frontend.leakage_envelope`).
        See :data:`LEAKAGE` for why and what it measured. Only the bins that pass the other
        tests are checked, so ``class_bins`` (e.g. a bank's bins) keeps this cheap.

    Returns
    -------
    numpy.ndarray, bool (..., n_bins)
        Silent bins are never valid (the comparison is strict).
    """
    x = check_spectra(spectra)
    n_bins = x.shape[-1]
    if not (np.isfinite(factor) and factor > 0):
        raise ConfigError(f"factor must be a finite number > 0, got {factor}")
    noise = np.asarray(noise_power, dtype=float)
    try:
        noise = np.broadcast_to(noise, (2, n_bins))
    except ValueError:
        raise ConfigError(f"noise_power must broadcast to (2, {n_bins}), got shape {noise.shape}") from None
    if not np.all(np.isfinite(noise)) or np.any(noise < 0):
        raise ConfigError("noise_power must be finite and >= 0")
    power = np.abs(x[..., 0, :].astype(np.complex128)) ** 2 + np.abs(x[..., 1, :].astype(np.complex128)) ** 2
    valid = power > factor * (noise[0] + noise[1])
    if class_bins is not None:
        valid = valid & bin_mask(class_bins, n_bins, "class_bins")
    if not (np.isfinite(leakage) and leakage >= 0):
        raise ConfigError(f"leakage must be a finite number >= 0, got {leakage}")
    if leakage > 0:
        valid = valid & _free_of_leakage(power, valid, leakage, n_fft=2 * (n_bins - 1))
    return valid


LEAKAGE = 10.0
"""The leakage factor of the project's estimators (:func:`valid_bins`; the pipeline's and
``eval paper``'s SSDENet): a bin must hold 10 times (10 dB) more power than any other bin's
sidelobes can leak into it, the paper's margin over the noise applied to the window's own
leakage.

Why: a network interprets the ILD/IPD of its bin as a source at its frequency. Next to a
strong tone the window's sidelobes (-41 dB and below) fill the neighbouring bins with the
tone's own interaural phasors, far above the paper's noise threshold (a test tone 40 dB
over the sensor noise has about 69 dB of SNR in its peak bin), so the 624-1507 Hz networks
read a 1 kHz tone's IPD as a 624 Hz source's, and vote for the wrong directions.
Measurements (the factor and the alternatives compared): docs/notes/ssdenet_recipes.md."""


_LEAKAGE_CHUNK = 1 << 22
"""Elements of the (frames, bins, bins) products computed at once by :func:`_free_of_leakage`."""


@functools.lru_cache(maxsize=2)
def _leakage_matrix(n_fft: int) -> np.ndarray:
    """(n_bins, n_bins) float64: the envelope of the leakage from bin j into bin i (8 MB for 1025 bins)."""
    env = leakage_envelope(n_fft)
    n = env.size
    m = env[np.abs(np.arange(n)[:, None] - np.arange(n)[None, :])]
    m.setflags(write=False)
    return m


def _free_of_leakage(power: np.ndarray, candidates: np.ndarray, factor: float, n_fft: int) -> np.ndarray:
    """power (..., n_bins), candidates bool (..., n_bins) -> bool (..., n_bins): the candidate
    bins whose power exceeds ``factor`` times the sidelobe leakage of every other bin."""
    out = np.zeros(candidates.shape, bool)
    flat_p = power.reshape(-1, power.shape[-1])
    flat_c = candidates.reshape(-1, power.shape[-1])
    flat_o = out.reshape(-1, power.shape[-1])
    cols = np.flatnonzero(flat_c.any(axis=0))
    if cols.size == 0:
        return out
    spread = _leakage_matrix(n_fft)[cols]  # (n_cols, n_bins): leakage from every bin into each column
    step = max(1, _LEAKAGE_CHUNK // spread.size)
    for lo in range(0, flat_p.shape[0], step):
        p = flat_p[lo:lo + step]
        leak = np.max(p[:, None, :] * spread[None], axis=-1)  # (frames, n_cols)
        flat_o[lo:lo + step, cols] = flat_c[lo:lo + step][:, cols] & (p[:, cols] > factor * leak)
    return out
