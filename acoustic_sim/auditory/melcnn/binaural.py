"""MelCNN's binaural fusion: the two ears' class probabilities weighted by the ears' volumes.

:func:`fuse`: ``p = (V_l p_l + V_r p_r) / (V_l + V_r)`` with V the ear volumes
(:func:`~acoustic_sim.auditory.features.ear_volume`, mean over the patch's frames:
:func:`patch_volumes`); when both ears are silent (``V_l + V_r = 0``) it is the plain mean
of the two ears.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.auditory import features as feat
from acoustic_sim.errors import ConfigError


def fuse(p_left, p_right, v_left, v_right) -> np.ndarray:
    """The paper's volume-weighted fusion of the two ears' probabilities.

    ``p = (V_l p_l + V_r p_r) / (V_l + V_r)``; where ``V_l + V_r == 0`` (both ears silent)
    the result is the plain mean ``(p_l + p_r) / 2``.

    Parameters
    ----------
    p_left, p_right : array_like
        (..., C) per-ear class probabilities in [0, 1].
    v_left, v_right : array_like
        (...) ear volumes (any non-negative loudness measure, e.g. mean power).

    Returns
    -------
    numpy.ndarray
        float64 (..., C) fused probabilities.

    Raises
    ------
    ConfigError
        Mismatched shapes, probabilities outside [0, 1], or negative / non-finite volumes.
    """
    pl, pr = np.asarray(p_left, np.float64), np.asarray(p_right, np.float64)
    vl, vr = np.asarray(v_left, np.float64), np.asarray(v_right, np.float64)
    if pl.shape != pr.shape or pl.ndim < 1:
        raise ConfigError(f"left and right probabilities must have the same shape (..., C), got {pl.shape} and {pr.shape}")
    if vl.shape != vr.shape or vl.shape != pl.shape[:-1]:
        raise ConfigError(f"volumes must have shape {pl.shape[:-1]} (the probabilities' without the class axis), "
                          f"got {vl.shape} and {vr.shape}")
    for p in (pl, pr):
        if not np.all((p >= 0) & (p <= 1)):
            raise ConfigError("probabilities must lie in [0, 1] (NaN is not allowed)")
    for v in (vl, vr):
        if not np.all(np.isfinite(v) & (v >= 0)):
            raise ConfigError("ear volumes must be finite and >= 0")
    return fuse_unchecked(pl, pr, vl, vr)


def fuse_unchecked(pl: np.ndarray, pr: np.ndarray, vl, vr) -> np.ndarray:
    """:func:`fuse` without its argument checks, for callers whose inputs are valid by
    construction (the streaming pipeline, once per frame): float64 arrays ``pl``, ``pr``
    (..., C) and volumes ``vl``, ``vr`` (...) or floats."""
    vl, vr = np.asarray(vl, np.float64), np.asarray(vr, np.float64)
    total = (vl + vr)[..., None]
    if total.ndim == 1:  # one frame: plain arithmetic, the same operations as the array form
        t = float(total[0])
        return 0.5 * (pl + pr) if t == 0 else (vl[..., None] * pl + vr[..., None] * pr) / t
    silent = total == 0
    safe = np.where(silent, 1.0, total)
    weighted = (vl[..., None] * pl + vr[..., None] * pr) / safe
    return np.where(silent, 0.5 * (pl + pr), weighted)


def patch_volumes(spectra) -> np.ndarray:
    """Ear volumes of a patch for :func:`fuse`: mean ear volume over its frames.

    spectra (..., T, 2, n_bins) complex -> float64 (..., 2).
    """
    x = np.asarray(spectra)
    if x.ndim < 3 or x.shape[-2] != 2:
        raise ConfigError(f"spectra must have shape (..., T, 2, n_bins), got {x.shape}")
    return feat.ear_volume(x).mean(axis=-2)
