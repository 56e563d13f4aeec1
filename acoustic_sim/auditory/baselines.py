"""Engineering baselines for binaural direction estimation: MUSIC and GCC-PHAT.

Both take the ear front end's frame spectra (``Frames.spectra``: complex (K, 2, n_bins),
left ear first, K >= 1 frames of one recording) and return a direction in the head frame of
:mod:`acoustic_sim.frames` (x forward, y left, z up; azimuth left positive, degrees).

MUSIC (Schmidt 1986) with HRTF steering vectors, as in the paper's comparison
--------------------------------------------------------------------------------
For every analysed bin w the 2 x 2 spatial correlation matrix is
``R(w) = (1/K) sum_k x_k(w) x_k(w)^H`` with ``x = [X_l, X_r]^T``. One source is assumed, so
the noise subspace is the eigenvector ``e_n(w)`` of the smaller eigenvalue, and the
pseudo-spectrum of grid direction d is::

    P(d, w) = |a(d, w)|^2 / |a(d, w)^H e_n(w)|^2

with ``a(d, w) = [A_l(d, w), A_r(d, w)]^T`` the HRTF of the measured direction nearest to d.
No spatial smoothing (the paper: the matrix is only 2 x 2). Bins are selected by the
eigenvalue ratio (Mohan et al. 2008, "Localization of multiple acoustic sources with small
arrays using a coherence test"): a bin where one source dominates has a nearly rank-one R,
so bins with ``lambda_max / lambda_min > ratio_threshold`` (default 10, i.e. the dominant
component 10 dB above the other) are kept. Bins whose ``lambda_max`` is more than
``-min_power_db`` (default 60 dB) below the strongest analysed bin are dropped as empty
before the ratio test: with a noiseless signal, window leakage makes every bin exactly
rank one (ratio infinite) however little energy it holds. With a single frame R is rank
one in every bin, so the ratio test passes everywhere and only the power floor selects.

Each selected bin's pseudo-spectrum is scaled to unit maximum over the grid, so every bin
casts one vote of the same weight whatever the sharpness of its peak (the raw peak height
``1 / (1 - coherence)`` is unbounded and would let one bin decide); the result is the mean
of those unit-max spectra over the selected bins (values in [0, 1]), and the estimate its
argmax. If no bin passes the ratio test, every bin above the power floor is used instead and
the result says so (``MusicResult.fallback``). A silent input (every eigenvalue at most
:data:`SILENCE_POWER`) gives an all-zero spectrum, ``silent=True`` and the grid direction
nearest straight ahead.

GCC-PHAT (Knapp & Carter 1976)
------------------------------
The interaural cross-spectrum ``G(w) = sum_k X_l X_r^*`` over the frames, PHAT-weighted
(``G / |G|``) inside ``band_hz`` and zero outside, is inverse-transformed with 8x
zero-padding; the peak lag within +- the largest ITD of the HRTF (plus 2 samples) is refined
by parabolic interpolation. The lag is the interaural time difference
``ITD = t_right - t_left`` in samples (positive: the left ear leads, the source is on the
left). It becomes a lateral angle through a lookup calibrated on the HRTF itself: the same
estimator applied to the HRTF's transfer functions at elevation 0, azimuth -90..90 deg in
5 deg steps (interpolated where the set has no measurement), made monotonic, and inverted by
linear interpolation (lags beyond the table clamp to +-90 deg). This works for any HRTF,
unlike a spherical-head formula. Limitation: one ITD describes a whole cone of confusion,
so the answer is always in the front half of the horizontal plane (azimuth -90..90 deg,
elevation 0); a source behind or above is reported at its mirror image in front. Silence
(zero cross-spectrum) gives straight ahead (azimuth 0) with ``silent=True``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError, HRTFError
from acoustic_sim.frames import sph_to_vec, unit_vectors

DEFAULT_MUSIC_BAND_HZ = (200.0, 12000.0)
"""Default MUSIC band (Hz): below 200 Hz the HRTFs of all directions are nearly equal (no
information), above 12 kHz the measured HRTFs vary faster than the grid resolves."""

DEFAULT_GCC_BAND_HZ = (100.0, 16000.0)
"""Default GCC-PHAT band (Hz)."""

SILENCE_POWER = 1e-24
"""Eigenvalue / cross-power (full-scale units squared) at or below which a bin is silent."""

_GCC_UPSAMPLE = 8
_CALIBRATION_AZIMUTHS_DEG = np.arange(-90.0, 90.0 + 1e-9, 5.0)


def _check_spectra(spectra, n_bins: int) -> np.ndarray:
    """Validated complex128 spectra (K, 2, n_bins)."""
    x = np.asarray(spectra)
    if x.ndim != 3 or x.shape[1] != 2 or x.shape[2] != n_bins:
        raise ConfigError(f"spectra must have shape (K, 2, {n_bins}) (frames, left/right, bins), got {x.shape}")
    if x.shape[0] == 0:
        raise ConfigError("spectra hold no frames (K = 0): nothing to localise")
    if not (np.issubdtype(x.dtype, np.number) and not np.issubdtype(x.dtype, np.bool_)):
        raise ConfigError(f"spectra must be numbers, got dtype {x.dtype}")
    x = x.astype(np.complex128, copy=False)
    if not np.all(np.isfinite(x)):
        raise ConfigError("spectra contain NaN or inf")
    return x


def _band_bins(band_hz, n_fft: int, sample_rate: int, what: str) -> np.ndarray:
    lo, hi = (float(v) for v in band_hz)
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo < hi <= sample_rate / 2):
        raise ConfigError(f"{what} must satisfy 0 <= low < high <= {sample_rate / 2} Hz, got {band_hz}")
    freqs = np.fft.rfftfreq(n_fft, 1.0 / sample_rate)
    bins = np.flatnonzero((freqs >= lo) & (freqs <= hi))
    if bins.size == 0:
        raise ConfigError(f"{what} {band_hz} Hz contains no rFFT bin for n_fft={n_fft}")
    return bins


@dataclass(frozen=True)
class MusicResult:
    """Everything MUSIC computed for one recording.

    Attributes
    ----------
    spectrum : numpy.ndarray
        float64 (D,): mean over the selected bins of the unit-max pseudo-spectra, in [0, 1].
    vector : numpy.ndarray
        float64 (3,): unit vector of the estimated grid direction (head frame).
    azimuth_deg, elevation_deg : float
        The estimate in degrees.
    index : int
        Grid index of the estimate.
    bins : numpy.ndarray
        int64 (B,): rFFT bins that were summed.
    fallback : bool
        True when no bin passed the eigenvalue-ratio test and every non-empty bin was used.
    silent : bool
        True when the input held no energy in the analysed bins (spectrum all zero).
    """

    spectrum: np.ndarray
    vector: np.ndarray
    azimuth_deg: float
    elevation_deg: float
    index: int
    bins: np.ndarray
    fallback: bool
    silent: bool


class Music:
    """MUSIC direction estimation with HRTF steering vectors (see the module docstring).

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        Steering vectors: its transfer functions at the grid directions.
    grid : acoustic_sim.directions.DirectionGrid
        The D candidate directions.
    bins : array_like of int, optional
        rFFT bins to analyse (indices into the last axis of the spectra); default every bin
        within :data:`DEFAULT_MUSIC_BAND_HZ`.
    n_fft : int
        FFT length of the front end (default 2048: 1025 bins).
    ratio_threshold : float
        Eigenvalue ratio ``lambda_max / lambda_min`` a bin must exceed to be used, > 1
        (default 10).
    min_power_db : float
        Bins whose ``lambda_max`` lies more than ``-min_power_db`` dB below the strongest
        analysed bin are ignored, < 0 (default -60).
    mode : {"nearest", "interpolated"}
        How the HRTF is looked up at grid directions it did not measure.

    Attributes
    ----------
    steering : numpy.ndarray
        complex128 (D, B, 2): the steering vectors a(d, w) of the analysed bins.
    bins : numpy.ndarray
        int64 (B,): the analysed bins.
    """

    def __init__(self, hrtf, grid, bins=None, *, n_fft: int = 2048, ratio_threshold: float = 10.0,
                 min_power_db: float = -60.0, mode: str = "nearest") -> None:
        if not (isinstance(n_fft, (int, np.integer)) and n_fft >= 16 and n_fft % 2 == 0):
            raise ConfigError(f"n_fft must be an even integer >= 16, got {n_fft!r}")
        if not (np.isfinite(ratio_threshold) and ratio_threshold > 1.0):
            raise ConfigError(f"ratio_threshold must be a finite number > 1, got {ratio_threshold}")
        if not (np.isfinite(min_power_db) and min_power_db < 0.0):
            raise ConfigError(f"min_power_db must be a finite number < 0 dB, got {min_power_db}")
        if not isinstance(grid, DirectionGrid):
            raise ConfigError(f"grid must be a DirectionGrid, got {type(grid).__name__}")
        self.n_fft = int(n_fft)
        self.n_bins = self.n_fft // 2 + 1
        if bins is None:
            b = _band_bins(DEFAULT_MUSIC_BAND_HZ, self.n_fft, hrtf.sample_rate, "DEFAULT_MUSIC_BAND_HZ")
        else:
            b = np.asarray(bins)
            if b.ndim != 1 or b.size == 0 or b.dtype == bool or not np.issubdtype(b.dtype, np.integer):
                raise ConfigError(f"bins must be a non-empty 1-D array of integer bin indices, got {bins!r}")
            if b.min() < 0 or b.max() >= self.n_bins:
                raise ConfigError(f"bins must lie in 0..{self.n_bins - 1} for n_fft={self.n_fft}")
            if np.unique(b).size != b.size:
                raise ConfigError("bins must not repeat")
        self.hrtf = hrtf
        self.grid = grid
        self.bins = b.astype(np.int64)
        self.ratio_threshold = float(ratio_threshold)
        self.min_power_db = float(min_power_db)
        a = hrtf.transfer_function(grid.vectors, n_fft=self.n_fft, bins=self.bins, mode=mode)  # (D, 2, B)
        self.steering = np.ascontiguousarray(np.transpose(a, (0, 2, 1)).astype(np.complex128))
        self.steering.flags.writeable = False
        # Conjugated ear components as separate contiguous (D, B) arrays: a^H e_n is then two
        # multiply-adds, several times faster than an einsum over the trailing axis of 2.
        self._conj_l = np.conj(self.steering[..., 0])
        self._conj_r = np.conj(self.steering[..., 1])
        self._steering_power = np.sum(np.abs(self.steering) ** 2, axis=-1)  # (D, B)
        self._front = int(grid.nearest(np.array([1.0, 0.0, 0.0])))

    def correlation(self, spectra) -> np.ndarray:
        """Spatial correlation matrices R(w) of the analysed bins, complex128 (B, 2, 2).

        ``spectra`` is complex (K, 2, n_bins); R is the mean over the K frames of x x^H.
        """
        x = _check_spectra(spectra, self.n_bins)[:, :, self.bins]  # (K, 2, B)
        return np.einsum("kib,kjb->bij", x, np.conj(x)) / x.shape[0]

    def analyze(self, spectra) -> MusicResult:
        """The full MUSIC result for one recording's spectra, complex (K, 2, n_bins)."""
        return self.analyze_correlation(self.correlation(spectra))

    def analyze_correlation(self, r) -> MusicResult:
        """The MUSIC result of correlation matrices R(w) of the analysed bins, complex (B, 2, 2)
        (:meth:`correlation`; a long recording can sum them over blocks of frames)."""
        r = np.asarray(r)
        if r.shape != (self.bins.size, 2, 2) or not np.all(np.isfinite(r)):
            raise ConfigError(f"correlation must be finite with shape ({self.bins.size}, 2, 2), got {r.shape}")
        # eigh sorts ascending: column 0 is the noise subspace of a single source.
        lam, vec = np.linalg.eigh(r)
        lam = np.clip(lam, 0.0, None)
        lam_max, lam_min = lam[:, 1], lam[:, 0]
        if not np.any(lam_max > SILENCE_POWER):
            return self._result(np.zeros(len(self.grid)), np.zeros(0, np.int64), fallback=False, silent=True)
        floor = max(lam_max.max() * 10.0 ** (self.min_power_db / 10.0), SILENCE_POWER)
        loud = lam_max > floor
        single = loud & (lam_max > self.ratio_threshold * lam_min)
        fallback = not single.any()
        use = loud if fallback else single
        e_n = vec[use, :, 0]  # (S, 2): the noise subspace of each selected bin
        if use.all():
            conj_l, conj_r, power = self._conj_l, self._conj_r, self._steering_power
        else:
            conj_l, conj_r, power = self._conj_l[:, use], self._conj_r[:, use], self._steering_power[:, use]
        z = conj_l * e_n[:, 0]
        z += conj_r * e_n[:, 1]  # a^H e_n, (D, S)
        proj = z.real**2 + z.imag**2
        # |a^H e_n|^2 <= |a|^2; the floor caps P at 1e12 where a lies in the signal subspace.
        p = power / np.maximum(proj, 1e-12 * power + 1e-300)
        top = p.max(axis=0)
        p = np.divide(p, top, out=np.zeros_like(p), where=top > 0)
        return self._result(p.mean(axis=1), self.bins[use], fallback=fallback, silent=False)

    def _result(self, spectrum, bins, *, fallback: bool, silent: bool) -> MusicResult:
        i = self._front if silent else int(np.argmax(spectrum))
        return MusicResult(spectrum=spectrum, vector=self.grid.vectors[i].copy(),
                           azimuth_deg=float(self.grid.azimuth_deg[i]), elevation_deg=float(self.grid.elevation_deg[i]),
                           index=i, bins=bins, fallback=fallback, silent=silent)

    def spectrum(self, spectra) -> np.ndarray:
        """MUSIC spectrum over the grid, float64 (D,) in [0, 1], of spectra complex (K, 2, n_bins)."""
        return self.analyze(spectra).spectrum

    def estimate(self, spectra) -> tuple[np.ndarray, float, float]:
        """Estimated direction of spectra complex (K, 2, n_bins).

        Returns
        -------
        vector : numpy.ndarray
            float64 (3,), unit vector of the best grid direction (head frame).
        azimuth_deg, elevation_deg : float
            The same direction in degrees.
        """
        res = self.analyze(spectra)
        return res.vector, res.azimuth_deg, res.elevation_deg


@dataclass(frozen=True)
class GccPhatResult:
    """GCC-PHAT result for one recording.

    Attributes
    ----------
    itd_samples : float
        Interaural time difference ``t_right - t_left`` in samples (positive: left leads).
    vector : numpy.ndarray
        float64 (3,): unit vector in the front half of the horizontal plane.
    azimuth_deg : float
        Lateral angle in deg, -90..90 (left positive).
    elevation_deg : float
        Always 0.
    silent : bool
        True when the cross-spectrum was zero (the estimate is then straight ahead).
    """

    itd_samples: float
    vector: np.ndarray
    azimuth_deg: float
    elevation_deg: float
    silent: bool


class GccPhat:
    """Interaural GCC-PHAT with an HRTF-calibrated lag-to-azimuth lookup (module docstring).

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        Calibrates the lookup (its horizontal-plane ITDs) and the largest lag searched.
    n_fft : int
        FFT length of the front end (default 2048).
    band_hz : tuple of float
        Band (Hz) of the PHAT-weighted cross-spectrum (default :data:`DEFAULT_GCC_BAND_HZ`).

    Attributes
    ----------
    table_azimuth_deg, table_itd_samples : numpy.ndarray
        float64 (37,): the calibration, azimuth -90..90 deg and its (monotonic) ITD.
    max_lag_samples : float
        Largest |lag| searched (the table's largest |ITD| + 2 samples).
    """

    def __init__(self, hrtf, *, n_fft: int = 2048, band_hz=DEFAULT_GCC_BAND_HZ) -> None:
        if not (isinstance(n_fft, (int, np.integer)) and n_fft >= 16 and n_fft % 2 == 0):
            raise ConfigError(f"n_fft must be an even integer >= 16, got {n_fft!r}")
        self.hrtf = hrtf
        self.n_fft = int(n_fft)
        self.n_bins = self.n_fft // 2 + 1
        self.sample_rate = hrtf.sample_rate
        self._mask = np.zeros(self.n_bins, bool)
        self._mask[_band_bins(band_hz, self.n_fft, hrtf.sample_rate, "band_hz")] = True
        az = _CALIBRATION_AZIMUTHS_DEG
        a = hrtf.transfer_function(azimuth_deg=az, elevation_deg=np.zeros_like(az), n_fft=self.n_fft,
                                   mode="interpolated")  # (37, 2, F)
        half_ms = 0.0015 * self.sample_rate  # a generous +-1.5 ms for the calibration search
        itd = self._peak_lag(a[:, 0] * np.conj(a[:, 1]), half_ms)
        if np.any(np.isnan(itd)):
            raise HRTFError(f"HRTF {hrtf.name!r} has no interaural cross-power in band_hz {band_hz}: cannot calibrate")
        # A lookup needs a strictly increasing table: clip dips (the ITD of measured heads
        # saturates, and can wobble, near +-90 deg), then break any ties with a tiny ramp
        # centred on azimuth 0 (a symmetric table keeps ITD 0 at azimuth 0).
        itd = np.maximum.accumulate(itd)
        if np.any(np.diff(itd) <= 0):
            itd = itd + 1e-6 * (np.arange(az.size) - az.size // 2)
        self.table_azimuth_deg = az.copy()
        self.table_itd_samples = itd
        self.max_lag_samples = float(np.max(np.abs(itd)) + 2.0)

    def _peak_lag(self, cross: np.ndarray, max_lag: float) -> np.ndarray:
        """ITDs (samples) of cross-spectra X_l X_r^* (..., n_bins), searched within +-max_lag;
        NaN where the band holds no cross-power. Shape (...)."""
        size = np.abs(cross)
        ok = self._mask & (size > SILENCE_POWER)
        phat = np.where(ok, cross / np.where(ok, size, 1.0), 0.0)
        n = self.n_fft * _GCC_UPSAMPLE
        r = np.fft.irfft(phat, n, axis=-1)
        # r[m] peaks at m = (t_left - t_right) * upsample (mod n); look at |lag| <= max_lag.
        m_max = int(np.floor(max_lag * _GCC_UPSAMPLE))
        m = np.arange(-m_max, m_max + 1)
        vals = r[..., m % n]
        j = np.argmax(vals, axis=-1)
        inner = np.clip(j, 1, m.size - 2)
        y0, y1, y2 = (np.take_along_axis(vals, (inner + o)[..., None], -1)[..., 0] for o in (-1, 0, 1))
        denom = y0 - 2.0 * y1 + y2
        # Parabolic refinement, only for an interior maximum of a concave triple.
        refine = (j == inner) & (denom < 0)
        shift = np.where(refine, 0.5 * (y0 - y2) / np.where(refine, denom, -1.0), 0.0)
        lag = -(m[j] + shift) / _GCC_UPSAMPLE
        return np.where(ok.any(axis=-1), lag, np.nan)

    def itd_to_azimuth(self, itd_samples) -> np.ndarray:
        """Lateral angle in deg (-90..90) of ITDs in samples (array_like), by the calibration."""
        return np.interp(np.asarray(itd_samples, float), self.table_itd_samples, self.table_azimuth_deg)

    def analyze(self, spectra) -> GccPhatResult:
        """The GCC-PHAT result of spectra complex (K, 2, n_bins)."""
        x = _check_spectra(spectra, self.n_bins)
        return self.analyze_cross(np.sum(x[:, 0] * np.conj(x[:, 1]), axis=0))

    def analyze_cross(self, cross) -> GccPhatResult:
        """The GCC-PHAT result of an interaural cross-spectrum ``sum_k X_l X_r^*``, complex
        (n_bins,) (a long recording can sum it over blocks of frames)."""
        cross = np.asarray(cross)
        if cross.shape != (self.n_bins,) or not np.all(np.isfinite(cross)):
            raise ConfigError(f"cross-spectrum must be finite with shape ({self.n_bins},), got {cross.shape}")
        itd = float(self._peak_lag(cross, self.max_lag_samples))
        if np.isnan(itd):
            return GccPhatResult(0.0, np.array([1.0, 0.0, 0.0]), 0.0, 0.0, silent=True)
        az = float(self.itd_to_azimuth(itd))
        return GccPhatResult(float(itd), unit_vectors(sph_to_vec(az, 0.0)), az, 0.0, silent=False)

    def estimate(self, spectra) -> tuple[np.ndarray, float, float]:
        """Direction (unit vector (3,), azimuth deg in -90..90, elevation 0.0) of spectra
        complex (K, 2, n_bins); front hemisphere of the horizontal plane only."""
        res = self.analyze(spectra)
        return res.vector, res.azimuth_deg, res.elevation_deg
