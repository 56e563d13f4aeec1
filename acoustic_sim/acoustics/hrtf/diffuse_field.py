"""Diffuse-field statistics of an HRTF set: solid-angle weights of its directions, the
direction-averaged power per ear and the interaural coherence of a diffuse field (the
late reverberation's spectrum and coherence, and the scale of loaded sets)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import SphericalVoronoi


class DiffuseField:
    """Diffuse-field statistics of :class:`~acoustic_sim.acoustics.hrtf.HRTF` (a base class).

    Uses the set's ``directions`` (D, 3), ``min_elevation_deg``, ``max_elevation_deg``,
    :meth:`spectra`, the KD-tree ``_tree()`` and its ``_cache`` dict (the weights).
    """

    def solid_angle_weights(self) -> np.ndarray:
        """Solid-angle weight of each measured direction.

        Each direction's spherical Voronoi cell area, restricted to the covered band
        (elevation range +- half the largest nearest-neighbour angle); sample counts of a
        Fibonacci sphere where the Voronoi diagram fails (degenerate sets).

        Returns
        -------
        numpy.ndarray, float, shape (D,)
            Weights >= 0 summing to 1, read-only.
        """
        if "weights" in self._cache:
            return self._cache["weights"]
        pts = self.directions
        n_samples = 40_000
        # Fibonacci sphere: a dense near-uniform sample to measure the covered cell fractions.
        k = np.arange(n_samples) + 0.5
        z = 1 - 2 * k / n_samples
        phi = np.pi * (1 + 5**0.5) * k
        sample = np.stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z], 1)
        if pts.shape[0] > 1:
            dist, _ = self._tree().query(pts, k=2)
            margin = np.rad2deg(2 * np.arcsin(np.clip(dist[:, 1].max() / 2, 0, 1))) / 2
        else:
            margin = 0.0
        el = np.rad2deg(np.arcsin(np.clip(sample[:, 2], -1, 1)))
        inside = (el >= self.min_elevation_deg - margin) & (el <= self.max_elevation_deg + margin)
        _, owner = self._tree().query(sample)
        total = np.bincount(owner, minlength=pts.shape[0]).astype(float)
        covered = np.bincount(owner[inside], minlength=pts.shape[0]).astype(float)
        try:
            area = SphericalVoronoi(pts, radius=1.0, threshold=1e-8).calculate_areas()
            frac = np.divide(covered, total, out=np.zeros_like(covered), where=total > 0)
            w = area * frac
        except Exception:  # noqa: BLE001 (degenerate sets: fall back to sample counts)
            w = covered
        if not np.sum(w) > 0:
            w = np.ones(pts.shape[0])
        w = w / np.sum(w)
        w.flags.writeable = False
        self._cache["weights"] = w
        return w

    def diffuse_field_power(self, n_fft: int = 2048) -> np.ndarray:
        """Direction-averaged power ``sum_d w_d |A_{l,r}(d, w)|^2`` per ear, with the weights
        of :meth:`solid_angle_weights`.

        Parameters
        ----------
        n_fft : int
            FFT length in samples, >= K (default 2048).

        Returns
        -------
        numpy.ndarray, float, shape (2, n_fft // 2 + 1)
            Power per ear and rFFT bin (dimensionless, >= 0).
        """
        w = self.solid_angle_weights()
        return np.einsum("d,dek->ek", w, np.abs(self.spectra(n_fft)) ** 2)

    def diffuse_field_coherence(self, n_fft: int = 2048) -> np.ndarray:
        """Real interaural coherence of a diffuse field.

        ``Re(sum_d w_d A_l A_r*) / sqrt(P_l P_r)`` with the solid-angle weights and the
        powers P of :meth:`diffuse_field_power`; 1 at DC.

        Parameters
        ----------
        n_fft : int
            FFT length in samples, >= K (default 2048); bin ``k`` is
            ``k * sample_rate / n_fft`` Hz.

        Returns
        -------
        numpy.ndarray, float, shape (n_fft // 2 + 1,)
            Coherence per rFFT bin, -1..1 (0 where a power is zero).
        """
        w = self.solid_angle_weights()
        spec = self.spectra(n_fft)
        cross = np.einsum("d,dk->k", w, spec[:, 0] * np.conj(spec[:, 1])).real
        p = self.diffuse_field_power(n_fft)
        denom = np.sqrt(p[0] * p[1])
        return np.divide(cross, denom, out=np.zeros_like(cross), where=denom > 0)
