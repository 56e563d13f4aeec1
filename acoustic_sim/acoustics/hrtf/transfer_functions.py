"""Transfer functions A_{l,r}(d, w) of an HRTF set: the rFFT spectra of its HRIRs, for the
measured directions or any others (the quantity the SSDENet data and MUSIC use)."""

from __future__ import annotations

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import sph_to_vec, unit_vectors


class TransferFunctions:
    """Spectra of :class:`~acoustic_sim.acoustics.hrtf.HRTF` (a base class of it).

    Uses the set's ``hrir`` (D, 2, K), ``n_taps``, :meth:`nearest_index`, :meth:`hrirs_for`
    and its ``_cache`` dict (the spectra per FFT length).
    """

    def _check_nfft(self, n_fft, bins):
        """The rFFT bin selection of ``bins`` after checking ``n_fft`` and ``bins``."""
        if not isinstance(n_fft, (int, np.integer)) or n_fft < self.n_taps:
            raise ConfigError(f"n_fft must be an integer >= the HRIR length {self.n_taps}, "
                              f"got {n_fft!r}")
        if bins is None:
            return slice(None)
        b = np.asarray(bins)
        if b.dtype == bool or not np.issubdtype(b.dtype, np.integer):
            raise ConfigError("bins must be integer rFFT bin indices")
        if b.size and (b.min() < 0 or b.max() > n_fft // 2):
            raise ConfigError(f"bins must lie in 0..{n_fft // 2} for n_fft={n_fft}")
        return b

    def spectra(self, n_fft: int = 2048, bins=None) -> np.ndarray:
        """Transfer functions A_{l,r}(d, w) of all measured directions.

        The rFFT of each HRIR zero-padded to ``n_fft``. Cached per ``n_fft``; without
        ``bins`` the shared, read-only cache is returned.

        Parameters
        ----------
        n_fft : int
            FFT length in samples, >= K (default 2048). Bin ``k`` is
            ``k * sample_rate / n_fft`` Hz.
        bins : array_like of int, optional
            rFFT bin indices to keep, 0..``n_fft // 2`` (default all ``n_fft // 2 + 1``).

        Returns
        -------
        numpy.ndarray, complex, shape (D, 2, n_bins)
            Left and right transfer functions (dimensionless).

        Raises
        ------
        ConfigError
            ``n_fft`` is not an integer >= K, or ``bins`` are not integer bins in range.
        """
        sel = self._check_nfft(n_fft, bins)
        key = ("spectra", int(n_fft))
        if key not in self._cache:
            spec = np.fft.rfft(self.hrir, int(n_fft), axis=-1)
            spec.flags.writeable = False
            self._cache[key] = spec
        spec = self._cache[key]
        return spec if bins is None else spec[..., sel]

    def transfer_function(self, vectors=None, *, azimuth_deg=None, elevation_deg=None,
                          n_fft: int = 2048, bins=None, mode: str = "nearest") -> np.ndarray:
        """Transfer functions for any directions (:meth:`hrirs_for`, then the rFFT).

        Give either ``vectors`` or both ``azimuth_deg`` and ``elevation_deg``.

        Parameters
        ----------
        vectors : array_like, shape (..., 3), optional
            Directions in the head frame, non-zero and finite.
        azimuth_deg, elevation_deg : array_like, optional
            Azimuth (left positive, any value) and elevation (-90..90) in degrees,
            broadcast against each other to shape (...).
        n_fft : int
            FFT length in samples, >= K (default 2048).
        bins : array_like of int, optional
            rFFT bin indices to keep, 0..``n_fft // 2`` (default all).
        mode : {"nearest", "interpolated"}
            Lookup (default ``"nearest"``).

        Returns
        -------
        numpy.ndarray, complex, shape (..., 2, n_bins)
            Left and right transfer functions (dimensionless).

        Raises
        ------
        ConfigError
            Both or neither direction forms, a bad ``n_fft``, ``bins`` or ``mode``.
        """
        sel = self._check_nfft(n_fft, bins)
        if (vectors is None) == (azimuth_deg is None or elevation_deg is None):
            raise ConfigError("give either vectors or both azimuth_deg and elevation_deg")
        v = unit_vectors(vectors) if vectors is not None else sph_to_vec(azimuth_deg, elevation_deg)
        if mode == "nearest":
            return self.spectra(n_fft)[self.nearest_index(v)][..., sel]
        return np.fft.rfft(self.hrirs_for(v, mode=mode), int(n_fft), axis=-1)[..., sel]
