"""Fusing the existence maps of several bins (and several looks) into one P(d).

The paper sums the maps of the valid bins; the default is n times their geometric mean,
which a bin that is confidently wrong cannot outvote (:data:`FUSIONS`; measurements:
docs/notes/fusion.md).
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.errors import ConfigError

FUSIONS = ("product", "sum")
"""How the existence maps of several bins make one P(d) (:func:`fuse`).

``"sum"``
    The paper's equation, P(d) = sum_i P(d, w_i).
``"product"``
    n times the geometric mean, P(d) = n exp(mean_i log max(P(d, w_i), FUSION_FLOOR)): the
    bins as independent pieces of evidence (a direction must be likely at every bin), the
    factor n weighting a frame by its number of valid bins when frames are summed, as the
    sum does.

Why the product is the default: under the sum a bin whose network is confidently wrong
outvotes the others, which matters most when few bins are valid (a square wave at 2 kHz
meets three of the paper bank's 32 bins). The floor keeps one bin's exact zero from vetoing
a direction.

Frames are still summed (each frame's fused map, :meth:`SSDENetBank.estimate`, the
pipeline's evidence window): a frame that holds another sound, or mostly reverberation,
would veto the right direction under a product over frames as well. The pipeline's onset
windows, several looks at one first wavefront, are pooled by :func:`pool_looks` like the
bins: their geometric mean under the product.

Measurements (simulation, room, tasks; the floor): docs/notes/fusion.md.
"""

DEFAULT_FUSION = "product"
"""The fusion :class:`SSDENetBank` and the pipeline use unless told (:data:`FUSIONS`).

ParkingBrake keeps the sum (:attr:`tasks.parking_brake.ParkingBrakeEnv.fusion`), where
the product measured worse. The sum stays available everywhere as ``fusion="sum"``
(``acoustic-sim localize --fusion sum``), and ``eval paper`` reports both. Measurements:
docs/notes/fusion.md."""

FUSION_FLOOR = 1e-4
"""Floor of each bin's P(d, w_i) under the product fusion (:data:`FUSIONS`)."""


def check_fusion(fusion: str) -> str:
    """``fusion`` if it is one of :data:`FUSIONS`, else a :class:`ConfigError`."""
    if fusion not in FUSIONS:
        raise ConfigError(f"unknown fusion {fusion!r}; valid: {', '.join(FUSIONS)}")
    return fusion


def fuse(existence, select, fusion: str = DEFAULT_FUSION) -> np.ndarray:
    """Fuse the existence maps of bins into P(d), for several selections of the bins at once.

    Parameters
    ----------
    existence : array_like, float (..., n, D)
        P(d, w_i) of n bins.
    select : array_like, bool or 0/1 (..., c, n)
        Which bins each of c selections uses (a frame's valid bins, a class's characteristic
        bins).
    fusion : str
        ``"product"`` or ``"sum"`` (:data:`FUSIONS`).

    Returns
    -------
    numpy.ndarray, float32 (..., c, D)
        Zero for a selection of no bin.
    """
    check_fusion(fusion)
    p = np.asarray(existence, np.float32)
    w = np.asarray(select).astype(np.float32)
    if fusion == "sum":
        return np.matmul(w, p)
    n = w.sum(axis=-1, keepdims=True)  # (..., c, 1)
    logs = np.matmul(w, np.log(np.maximum(p, np.float32(FUSION_FLOOR))))
    return np.where(n > 0, n * np.exp(logs / np.maximum(n, 1.0)), 0.0).astype(np.float32)


def pool_looks(existence, fusion: str = DEFAULT_FUSION) -> np.ndarray:
    """One existence map per bin from k looks at the same sound (onset windows).

    ``existence`` (k, ..., D) -> (..., D): the mean over the looks under the sum, their
    geometric mean (floored as in :func:`fuse`) under the product.
    """
    check_fusion(fusion)
    p = np.asarray(existence, np.float32)
    if fusion == "sum":
        return p.mean(axis=0)
    return np.exp(np.log(np.maximum(p, np.float32(FUSION_FLOOR))).mean(axis=0)).astype(np.float32)
