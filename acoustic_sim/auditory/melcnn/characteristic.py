"""MelCNN's characteristic bins: per class, the FFT bins that SSDENet sums over.

Per class, from the training data: the mean over the frames where the class was audible
(:mod:`~acoustic_sim.auditory.sound_data`) of its own unit-sum power spectrum at the ear,
then the smallest set of FFT bins holding ``energy_fraction`` (90 %) of that mean energy
(:func:`characteristic_bins`). The sets are stored in the checkpoint metadata and handed to
SSDENet as ``MelCNN.characteristic_bins: dict[str, numpy.ndarray]`` (int64 indices into
the 1025 bins, ascending).
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.auditory.sound_data import CLASSES
from acoustic_sim.errors import ConfigError


def characteristic_bins(spectrum_sum, spectrum_frames, *, energy_fraction: float = 0.9,
                        classes=CLASSES) -> dict[str, np.ndarray]:
    """The smallest set of FFT bins holding ``energy_fraction`` of each class's mean energy.

    Parameters
    ----------
    spectrum_sum : array_like
        (C, n_bins): per class, the sum of unit-sum power spectra over audible frames
        (:attr:`SoundExamples.spectrum_sum`).
    spectrum_frames : array_like
        (C,): the number of those frames.
    energy_fraction : float
        In (0, 1].
    classes : sequence of str
        Names of the C classes.

    Returns
    -------
    dict of str to numpy.ndarray
        Per class, int64 bin indices, ascending (bin i is at i * 44100 / 2048 Hz).

    Raises
    ------
    ConfigError
        A class with no audible frame (the data set is too small to characterise it).
    """
    s = np.asarray(spectrum_sum, np.float64)
    n = np.asarray(spectrum_frames)
    if s.ndim != 2 or s.shape[0] != len(classes) or n.shape != (len(classes),):
        raise ConfigError(f"spectrum_sum must be ({len(classes)}, n_bins) and spectrum_frames ({len(classes)},), "
                          f"got {s.shape} and {n.shape}")
    if not 0 < energy_fraction <= 1:
        raise ConfigError(f"energy_fraction must be in (0, 1], got {energy_fraction}")
    out = {}
    for c, name in enumerate(classes):
        if n[c] <= 0 or not np.any(s[c] > 0):
            raise ConfigError(f"class {name!r} is never audible in the data: cannot find its characteristic bins "
                              "(use more examples)")
        mean = s[c] / n[c]
        order = np.argsort(-mean, kind="stable")
        cum = np.cumsum(mean[order]) / mean.sum()
        k = int(np.searchsorted(cum, energy_fraction - 1e-12) + 1)
        out[name] = np.sort(order[:k]).astype(np.int64)
    return out
