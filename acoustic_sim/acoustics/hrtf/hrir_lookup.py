"""Looking up an HRTF set's responses for any direction: the nearest measured direction, or
barycentric interpolation on the spherical Delaunay triangulation with the onsets aligned
(the ``Lookup`` convention of :mod:`acoustic_sim.acoustics.hrtf`). Accuracy of the
interpolation: docs/notes/hrtf.md.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.fft import next_fast_len
from scipy.spatial import ConvexHull, cKDTree

from acoustic_sim.acoustics.hrtf.responses import delay_spectra
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import angle_between_deg, sph_to_vec, unit_vectors

_MODES = ("nearest", "interpolated")


class HRIRLookup:
    """Direction lookups of :class:`~acoustic_sim.acoustics.hrtf.HRTF` (a base class of it).

    Uses the set's ``hrir`` (D, 2, K), ``directions`` (D, 3), ``n_taps``, :meth:`onsets`,
    :meth:`covers` and its ``_cache`` dict, where the KD-tree, the triangulation and the
    onset-aligned spectra are kept.
    """

    def _tree(self) -> cKDTree:
        if "tree" not in self._cache:
            self._cache["tree"] = cKDTree(self.directions)
        return self._cache["tree"]

    def nearest_index(self, vectors) -> np.ndarray:
        """Index of the measured direction closest in angle to each vector.

        Parameters
        ----------
        vectors : array_like, shape (..., 3)
            Directions in the head frame, non-zero and finite (any length).

        Returns
        -------
        numpy.ndarray, int, shape (...)
            Indices into ``directions``, 0..D-1.
        """
        v = unit_vectors(vectors)
        _, idx = self._tree().query(v.reshape(-1, 3))
        return np.asarray(idx, dtype=np.intp).reshape(v.shape[:-1])

    def _triangulation(self):
        """Convex hull facets usable for interpolation: (normals, offsets, vertices,
        inverse vertex matrices, valid mask)."""
        if "hull" in self._cache:
            return self._cache["hull"]
        pts = self.directions
        n_real = pts.shape[0]
        hull = None
        try:
            hull = ConvexHull(pts)
            if np.max(hull.equations[:, 3]) > -1e-9:  # origin not inside: add a far anchor
                hull = None
        except Exception:  # noqa: BLE001 (QhullError: flat or tiny sets)
            hull = None
        if hull is None:
            # Anchor points opposite the data (or on both sides of a flat set): their facets
            # are marked invalid, so only genuine triangles of measured directions remain.
            _, _, vt = np.linalg.svd(pts - 0.0)
            mean = pts.mean(axis=0)
            anchors = [-mean / np.linalg.norm(mean)] if np.linalg.norm(mean) > 1e-6 else []
            anchors += [vt[-1], -vt[-1]]
            try:
                hull = ConvexHull(np.vstack([pts, anchors]))
            except Exception:  # noqa: BLE001
                self._cache["hull"] = None
                return None
        simplices = hull.simplices
        valid = np.all(simplices < n_real, axis=1)
        allpts = hull.points
        tri = allpts[simplices]  # (F, 3, 3)
        edges = np.stack([angle_between_deg(tri[:, 0], tri[:, 1]),
                          angle_between_deg(tri[:, 1], tri[:, 2]),
                          angle_between_deg(tri[:, 2], tri[:, 0])], axis=1).max(axis=1)
        if n_real > 1:
            dist, _ = self._tree().query(pts, k=2)
            nn = np.rad2deg(2 * np.arcsin(np.clip(dist[:, 1] / 2, 0, 1)))
            valid &= edges <= 3.0 * np.median(nn)
        with np.errstate(all="ignore"):
            inv = np.linalg.pinv(np.transpose(tri, (0, 2, 1)))  # columns are the vertices
        result = (hull.equations[:, :3], -hull.equations[:, 3], simplices, inv, valid)
        self._cache["hull"] = result
        return result

    def _locate(self, v: np.ndarray):
        """Triangle vertices (N, 3), barycentric weights (N, 3) and usability (N,) of unit
        vectors (N, 3)."""
        tri = self._triangulation()
        n = v.shape[0]
        if tri is None:
            return np.zeros((n, 3), int), np.zeros((n, 3)), np.zeros(n, bool)
        normals, offsets, simplices, inv, valid = tri
        n_cand = min(8, normals.shape[0])
        facet = np.empty(n, dtype=np.intp)
        for s in range(0, n, 2048):
            # The ray leaves the hull through the facet it hits first (largest n.v / offset).
            # Coplanar facets (a planar quad of a regular grid) tie, so check the barycentric
            # coordinates of the best few candidates and take the first that contains the ray.
            vs = v[s:s + 2048]
            score = (vs @ normals.T) / offsets
            cand = np.argpartition(-score, n_cand - 1, axis=1)[:, :n_cand]
            order = np.argsort(-np.take_along_axis(score, cand, 1), axis=1)
            cand = np.take_along_axis(cand, order, 1)
            bary = np.einsum("ncij,nj->nci", inv[cand], vs)
            inside = bary.min(axis=2) >= -1e-9 * np.abs(bary).sum(axis=2)
            first = np.where(inside.any(axis=1), np.argmax(inside, axis=1), 0)
            facet[s:s + 2048] = cand[np.arange(vs.shape[0]), first]
        w = np.einsum("nij,nj->ni", inv[facet], v)
        w = np.clip(w, 0.0, None)
        total = w.sum(axis=1, keepdims=True)
        ok = valid[facet] & (total[:, 0] > 0) & self.covers(v)
        w = np.where(total > 0, w / np.where(total > 0, total, 1.0), 0.0)
        return simplices[facet], w, ok

    def _aligned(self):
        """Onset-aligned spectra (D, 2, F) on a padded FFT grid, onsets (D, 2), n_fft."""
        if "aligned" not in self._cache:
            onsets = self.onsets()
            # Twice the needed length: the magnitude correction of hrirs_for then acts on a
            # grid fine enough that the spectrum does not dip between its bins.
            n_fft = int(next_fast_len(2 * (self.n_taps + 2 * math.ceil(onsets.max()) + 16)))
            spec = delay_spectra(np.fft.rfft(self.hrir, n_fft, axis=-1), n_fft, -onsets)
            self._cache["aligned"] = (spec, onsets, n_fft)
        return self._cache["aligned"]

    def hrirs_for(self, vectors, *, mode: str = "nearest") -> np.ndarray:
        """HRIRs for directions in the head frame.

        ``mode="nearest"`` returns the measured HRIR closest in angle; ``"interpolated"``
        interpolates onset-aligned HRIRs barycentrically on the Delaunay triangulation (the
        weighted mean of the aligned spectra, its magnitude replaced by the weighted mean of
        the magnitudes) and re-applies the interpolated onsets as a fractional delay. It
        falls back to nearest outside :meth:`covers` and in triangles that bridge a gap of
        the grid (edges longer than 3x the median nearest-neighbour angle). At a measured
        direction both modes return the measured HRIR. Above about 8 kHz, where pinna
        notches move by more than their width between neighbouring KEMAR directions, no
        interpolation of measured responses is exact; there the result can be up to ~10 dB
        off in narrow bands (measurements: docs/notes/hrtf.md).

        Parameters
        ----------
        vectors : array_like, shape (..., 3)
            Directions in the head frame, non-zero and finite (any length).
        mode : {"nearest", "interpolated"}
            Lookup (default ``"nearest"``).

        Returns
        -------
        numpy.ndarray, float, shape (..., 2, K)
            Left and right HRIRs (dimensionless), K = ``n_taps``.

        Raises
        ------
        ConfigError
            An unknown ``mode`` or invalid vectors.
        """
        if mode not in _MODES:
            raise ConfigError(f"mode must be one of {_MODES}, got {mode!r}")
        v = unit_vectors(vectors)
        shape = v.shape[:-1]
        v = v.reshape(-1, 3)
        nearest = self.nearest_index(v)
        out = self.hrir[nearest].copy()
        if mode == "interpolated" and v.shape[0]:
            idx, w, ok = self._locate(v)
            if ok.any():
                spec, onsets, n_fft = self._aligned()
                wi, ii = w[ok], idx[ok]
                mixed = np.einsum("nj,njrf->nrf", wi, spec[ii])
                # Keep the phase of the aligned mixture but take the weighted mean of the
                # magnitudes: where the neighbours' fine structure (pinna reflections) differs,
                # a complex mean would still cancel partly and dig notches neither has.
                mag = np.einsum("nj,njrf->nrf", wi, np.abs(spec[ii]))
                size = np.abs(mixed)
                mixed = np.where(size > 0, mixed * (mag / np.where(size > 0, size, 1.0)), mag)
                onset = np.einsum("nj,njr->nr", wi, onsets[ii])
                h = np.fft.irfft(delay_spectra(mixed, n_fft, onset), n_fft, axis=-1)
                out[ok] = h[..., : self.n_taps]
        return out.reshape(shape + (2, self.n_taps))

    def hrir_at(self, azimuth_deg: float, elevation_deg: float, *, mode: str = "nearest") -> np.ndarray:
        """HRIR pair for one direction given in degrees (:meth:`hrirs_for`).

        Parameters
        ----------
        azimuth_deg : float
            Azimuth in degrees, counter-clockwise from the nose (left positive), any value.
        elevation_deg : float
            Elevation in degrees, -90..90.
        mode : {"nearest", "interpolated"}
            Lookup (default ``"nearest"``).

        Returns
        -------
        numpy.ndarray, float, shape (2, K)
            Left and right HRIR (dimensionless).
        """
        return self.hrirs_for(sph_to_vec(azimuth_deg, elevation_deg), mode=mode)
