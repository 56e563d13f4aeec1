"""The sounds the streaming pipeline can localize, and the bins each may use.

A row per sound: the MelCNN's classes first, in their order, then the sounds an experiment
attends to (:meth:`SoundRows.attend`: white noise, which is no class, or a known sound with
its own bins). Each row has its characteristic bins among the SSDENet bank's bins (a class
without characteristic bins: all of them) and, for the specificity rule, among the bins of
:data:`~acoustic_sim.auditory.pipeline.settings.SPECIFICITY_BAND_HZ`.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.auditory.frontend import N_BINS, bin_frequencies
from acoustic_sim.auditory.pipeline.settings import SPECIFICITY_BAND_HZ
from acoustic_sim.errors import ConfigError


class SoundRows:
    """The localizable sounds: names, bank-bin masks, band masks, and which are attended.

    Parameters
    ----------
    classes : sequence of str
        The MelCNN's classes (the first rows, in order).
    characteristic_bins : mapping
        Class name -> indices into the 1025 bins (0..1024); missing or empty: every bin.
    bank_bins : array_like of int
        The SSDENet bank's bins (indices into the 1025), whose masks the rows hold.
    """

    def __init__(self, classes, characteristic_bins, bank_bins) -> None:
        self.classes = tuple(classes)
        self.names = list(self.classes)
        self.attended: list[int] = []  # rows localized in every frame
        self._bank_bins = np.asarray(bank_bins)
        f = bin_frequencies()
        self.band = (f >= SPECIFICITY_BAND_HZ[0]) & (f <= SPECIFICITY_BAND_HZ[1])
        # (rows, n_bank) bool: each row's characteristic bins among the bank's.
        self.masks = np.zeros((len(self.classes), self._bank_bins.size), bool)
        # (rows, n_band): which of the band's bins are characteristic (all of them for a class without).
        self.band_masks = np.ones((len(self.classes), int(self.band.sum())))
        for c, name in enumerate(self.classes):
            cb = characteristic_bins.get(name)
            self.masks[c] = np.isin(self._bank_bins, cb) if cb is not None and np.size(cb) else True
            if cb is not None and np.size(cb):
                own = np.zeros(N_BINS, bool)
                own[np.asarray(cb)] = True
                self.band_masks[c] = own[self.band]
        self.sizes = self.masks.sum(axis=1)  # (rows,)

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def attend(self, name: str, bins=None) -> int:
        """Localize ``name`` in every frame: a class, or another sound with its characteristic
        bins (indices into the 1025; None: all the bank's bins). Returns its row; a new row
        when ``name`` is no sound yet."""
        if name in self.names:
            if bins is not None and name in self.classes:
                raise ConfigError(f"{name!r} is a class: its characteristic bins are the MelCNN's")
            row = self.names.index(name)
        else:
            if not isinstance(name, str) or not name:
                raise ConfigError(f"an attended sound needs a name, got {name!r}")
            own = np.zeros(N_BINS, bool)
            try:
                own[np.arange(N_BINS) if bins is None else np.asarray(bins, np.int64)] = True
            except (IndexError, ValueError, TypeError):
                raise ConfigError(f"bins must be indices 0..{N_BINS - 1}, got {bins!r}") from None
            mask = own[self._bank_bins]
            if not mask.any():
                raise ConfigError(f"none of the bins given for {name!r} is one of the bank's")
            self.names.append(name)
            self.masks = np.vstack([self.masks, mask[None]])
            self.sizes = self.masks.sum(axis=1)
            self.band_masks = np.vstack([self.band_masks, own[self.band][None].astype(float)])
            row = len(self.names) - 1
        if row not in self.attended:
            self.attended.append(row)
        return row

    def clear_attention(self) -> None:
        """Localize only the detected classes again (the attended rows stay known)."""
        self.attended.clear()

    def bins(self, name: str) -> np.ndarray:
        """The bank bins (indices into the 1025) of sound ``name``."""
        return self._bank_bins[self.masks[self.index(name)]]

    def shares(self, power: np.ndarray) -> np.ndarray:
        """Per row, the share of ``power`` (per bin, (1025,)) within the specificity band that
        lies in the row's characteristic bins (1 for every row when the band is silent)."""
        e = power[self.band]
        total = float(e.sum())
        return self.band_masks @ e / total if total > 0 else np.ones(len(self.names))
