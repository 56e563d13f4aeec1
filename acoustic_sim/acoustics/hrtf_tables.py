"""What the binaural renderer derives from its HRTF alone, built once per HRTF and shared by
every renderer of it (:func:`hrtf_tables`): the nearest measured direction for any direction
(:class:`DirectionLookup`), the HRIRs at every fractional delay, and the filters of the room's
diffuse background noise (:class:`BackgroundNoise`), which this module also renders. The
renderer (:mod:`acoustic_sim.acoustics.renderer`) is their user.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import threading

import numpy as np

from acoustic_sim.acoustics.convolution import fractional_hrir_table
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import db_spl_to_pa

FRACTIONAL_PHASES = 8
"""Fractional-delay resolution of image placement (delay error <= 1/16 sample)."""


class DirectionLookup:
    """Nearest HRTF direction for any head-frame direction, by table.

    A KD-tree query costs about 1 us per direction in Python; the renderer asks for the
    direct path every block and for every image source at each reflection update. The
    table holds the nearest measured direction for the
    centre of every cell of a 0.5 deg azimuth x elevation grid (worst-case extra error
    0.35 deg, far below the HRTF's 5-10 deg spacing).
    """

    STEP = 0.5

    def __init__(self, hrtf) -> None:
        from acoustic_sim.frames import sph_to_vec

        az = np.arange(-180.0, 180.0, self.STEP) + self.STEP / 2
        el = np.arange(-90.0, 90.0, self.STEP) + self.STEP / 2
        grid = sph_to_vec(az[None, :], el[:, None])
        self.table = np.asarray(hrtf.nearest_index(grid.reshape(-1, 3)), dtype=np.int64).reshape(el.size, az.size)
        self._flat = self.table.ravel()
        self.table.flags.writeable = self._flat.flags.writeable = False  # shared (HRTFTables)

    def lookup(self, unit_vectors: np.ndarray) -> np.ndarray:
        v = unit_vectors
        rows, cols = self.table.shape
        per_rad = 180.0 / np.pi / self.STEP  # cells per radian
        # Cell of (az + 180, el + 90) on the 0.5 deg grid, in few array operations.
        i = (np.arcsin(np.maximum(np.minimum(v[:, 2], 1.0), -1.0)) * per_rad + 90.0 / self.STEP).astype(np.int64)
        j = (np.arctan2(v[:, 1], v[:, 0]) * per_rad + 180.0 / self.STEP).astype(np.int64)
        np.minimum(i, rows - 1, out=i)
        j %= cols
        i *= cols
        i += j
        return self._flat[i]

    def lookup_one(self, x: float, y: float, z: float) -> int:
        """:meth:`lookup` for one unit vector, in scalar arithmetic (no array overhead)."""
        az = math.atan2(y, x) * (180.0 / math.pi)
        el = math.asin(min(max(z, -1.0), 1.0)) * (180.0 / math.pi)
        i = min(int((el + 90.0) / self.STEP), self.table.shape[0] - 1)
        j = int((az + 180.0) / self.STEP) % self.table.shape[1]
        return int(self.table[i, j])


class BackgroundNoise:
    """Diffuse background noise at a room's level (dB SPL, unweighted), streamed.

    Spectrum: -4.5 dB per octave above 100 Hz (a typical indoor noise floor between
    pink and brown). Interaural coherence: a diffuse field is coherent at low frequencies
    and incoherent at high ones, like a common low-passed component plus independent
    high-passed components with the crossover where the HRTF's diffuse-field coherence
    falls to 0.5. The same second-order statistics come from two noises instead of three,
    as mid and side: left = M + S, right = M - S with ``S = tilt * HP / sqrt(2)`` and
    ``|M|^2 = |tilt|^2 (1 + |LP|^2) / 2``, a second-order shelf that is exact for the
    power-complementary Butterworth pair (|LP|^2 + |HP|^2 = 1): each ear's spectrum is
    ``|tilt|^2`` and the cross-spectrum ``|tilt|^2 |LP|^2``, as with a common low band.
    """

    def __init__(self, level_db: float, hrtf, rng: np.random.Generator, sample_rate: int) -> None:
        from scipy import signal

        self.rng = rng
        self.gain = float(db_spl_to_pa(level_db))
        design = hrtf_tables(hrtf).background_filters(sample_rate)
        self.crossover_hz = design.crossover_hz
        self.sos_mid, self.sos_side, self.norm = design.sos_mid, design.sos_side, design.norm
        self.zi_mid = np.zeros((self.sos_mid.shape[0], 2))
        self.zi_side = np.zeros((self.sos_side.shape[0], 2))
        self._signal = signal
        # Warm up the filters so the first block is already stationary.
        self._generate(1 << 14)
        self._buffer = np.zeros((2, 0))
        self._read = 0

    CHUNK = 32768

    def __call__(self, n: int) -> np.ndarray:
        """The next ``n`` samples (2, n) in Pa. Generated in chunks of :attr:`CHUNK`
        (filter calls have a fixed cost), so the stream does not depend on block sizes."""
        if self._read + n > self._buffer.shape[1]:
            parts = [self._buffer[:, self._read :]]
            have = parts[0].shape[1]
            while have < n:
                parts.append(self._generate(self.CHUNK))
                have += self.CHUNK
            self._buffer, self._read = np.concatenate(parts, axis=1), 0
        out = self._buffer[:, self._read : self._read + n]
        self._read += n
        return out

    def _generate(self, n: int) -> np.ndarray:
        sig = self._signal
        w = self.rng.standard_normal((2, n))
        mid, self.zi_mid = sig.sosfilt(self.sos_mid, w[0], zi=self.zi_mid)
        side, self.zi_side = sig.sosfilt(self.sos_side, w[1], zi=self.zi_side)
        g = self.norm * self.gain
        mid *= g
        side *= g
        return np.stack([mid + side, mid - side])


# -- tables shared by every renderer of one HRTF -----------------------------------------------

HRTF_TABLES_KEPT = 4
"""HRTFs whose derived tables :func:`hrtf_tables` keeps (the least recently used goes
first): about 31 MB each for the bundled KEMAR set."""


@dataclasses.dataclass(frozen=True)
class BackgroundFilters:
    """The filters of :class:`BackgroundNoise` for one HRTF and sample rate (see there).

    Attributes
    ----------
    crossover_hz : float
        Where the HRTF's diffuse-field coherence falls to 0.5 (clipped to 200-2000 Hz).
    sos_mid, sos_side : numpy.ndarray, shape (n_sections, 6)
        Second-order sections of the mid and side noises (tilt included).
    norm : float
        Gain that makes each ear's noise unit RMS for unit white input.
    """

    crossover_hz: float
    sos_mid: np.ndarray
    sos_side: np.ndarray
    norm: float


def _background_filters(coherence: np.ndarray, sample_rate: int) -> BackgroundFilters:
    """Design :class:`BackgroundFilters` from a diffuse-field coherence (1024-point rFFT bins)."""
    from scipy import signal

    freqs = np.fft.rfftfreq(1024, 1.0 / sample_rate)
    below = np.flatnonzero(coherence < 0.5)
    fc = float(np.clip(freqs[below[0]] if below.size else 700.0, 200.0, 2000.0))
    # -4.5 dB/octave tilt: a first-order shelf cascade approximates it over 100 Hz-10 kHz.
    zeros = [-2 * np.pi * f for f in (250.0, 1300.0, 7000.0)]
    poles = [-2 * np.pi * f for f in (100.0, 550.0, 3000.0)]
    z, p, k = signal.bilinear_zpk(zeros, poles, 1.0, sample_rate)
    tilt = signal.zpk2sos(z, p, k)
    high = signal.butter(2, fc, "high", fs=sample_rate, output="sos")
    # Mid shelf: (s^2 + 2^(3/4) s + sqrt 2) / (sqrt 2 (s^2 + sqrt 2 s + 1)) at the
    # Butterworth's pre-warped cut-off, through the same bilinear transform.
    wa = 2.0 * sample_rate * np.tan(np.pi * fc / sample_rate)
    mid_zeros = np.roots([1.0, 2.0**0.75, np.sqrt(2.0)]) * wa
    mid_poles = np.roots([1.0, np.sqrt(2.0), 1.0]) * wa
    z, p, k = signal.bilinear_zpk(mid_zeros, mid_poles, 1.0 / np.sqrt(2.0), sample_rate)
    sos_mid = np.vstack([tilt, signal.zpk2sos(z, p, k)])
    sos_side = np.vstack([tilt, high * np.array([1.0 / np.sqrt(2.0)] * 3 + [1.0] * 3)])
    # Normalize to unit RMS per ear for white input, measured once on a long burst.
    probe = np.random.default_rng(0).standard_normal((2, 1 << 17))
    m = signal.sosfilt(sos_mid, probe[0])
    side = signal.sosfilt(sos_side, probe[1])
    norm = 1.0 / np.sqrt(np.mean((m + side) ** 2))
    return BackgroundFilters(crossover_hz=fc, sos_mid=sos_mid, sos_side=sos_side, norm=float(norm))


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class HRTFTables:
    """What the renderer derives from its HRTF alone, built once and shared by every
    renderer of that HRTF.

    The fractional-delay HRIR tables and the direction lookup take about 0.3 s to build
    for KEMAR, which every :class:`~acoustic_sim.acoustics.renderer.BinauralRenderer` used to pay, i.e. every task
    episode's reset. They depend only on the HRTF's responses, directions and sample rate,
    all of which :attr:`~acoustic_sim.acoustics.hrtf.HRTF.ident` hashes, and an HRTF is
    immutable; so :func:`hrtf_tables` keeps one set per ident. The arrays are read-only:
    one renderer cannot change what another renders.

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF

    Attributes
    ----------
    ident : str
        The HRTF's ident (the cache key).
    hrir : numpy.ndarray, shape (D, FRACTIONAL_PHASES, 2 * (K + 1)), float32
        The full HRIRs at every fractional delay (:func:`fractional_hrir_table`): the
        direct path's responses.
    taps : int
        K + 1: samples per ear in a row of :attr:`hrir`.
    directions : DirectionLookup
        Nearest HRTF direction of any head-frame direction.
    """

    def __init__(self, hrtf) -> None:
        self._hrtf = hrtf
        self.ident: str = hrtf.ident
        self.hrir = _read_only(fractional_hrir_table(hrtf.hrir, FRACTIONAL_PHASES))
        self.taps = int(hrtf.hrir.shape[-1]) + 1
        self.directions = DirectionLookup(hrtf)
        self._short: dict[int, np.ndarray] = {}
        self._diffuse: tuple[np.ndarray, np.ndarray] | None = None
        self._background: dict[int, BackgroundFilters] = {}
        self._lock = threading.Lock()

    def short_hrir(self, taps: int) -> np.ndarray:
        """The HRIRs' first ``taps`` samples (4..K), faded out over their last quarter, at
        every fractional delay: shape (D, FRACTIONAL_PHASES, 2 * (taps + 1)), float32,
        read-only (the reflections' responses)."""
        if not isinstance(taps, (int, np.integer)) or not 4 <= taps <= self.taps - 1:
            raise ConfigError(f"reflection_taps must be an integer 4..{self.taps - 1} (the HRIR length), got {taps!r}")
        taps = int(taps)
        with self._lock:
            if taps not in self._short:
                hrir = self._hrtf.hrir
                fade = np.ones(taps)
                n_fade = taps // 4  # not fade[-taps // 4:]: that is (-taps) // 4, one too many
                fade[taps - n_fade :] = np.hanning(2 * n_fade)[n_fade:]
                self._short[taps] = _read_only(fractional_hrir_table(hrir[..., :taps] * fade, FRACTIONAL_PHASES))
            return self._short[taps]

    def diffuse_field(self) -> tuple[np.ndarray, np.ndarray]:
        """The HRTF's diffuse-field power (2, 513) and interaural coherence (513,) on a
        1024-point rFFT grid, read-only (the late tails' spectrum and coherence).

        HRIRs longer than 1024 samples are transformed on the shortest multiple of 1024
        points that holds them and every m-th bin is kept: the same frequencies, each value
        exact there (both quantities are per-bin), identical to a 1024-point rFFT otherwise."""
        with self._lock:
            if self._diffuse is None:
                h = self._hrtf
                m = max(1, -(-h.n_taps // 1024))
                self._diffuse = (_read_only(np.array(h.diffuse_field_power(1024 * m)[:, ::m])),
                                 _read_only(np.array(h.diffuse_field_coherence(1024 * m)[::m])))
            return self._diffuse

    def background_filters(self, sample_rate: int) -> BackgroundFilters:
        """The :class:`BackgroundNoise` filters at ``sample_rate`` (Hz)."""
        coherence = self.diffuse_field()[1]
        with self._lock:
            if sample_rate not in self._background:
                self._background[sample_rate] = _background_filters(coherence, int(sample_rate))
            return self._background[sample_rate]


_TABLES: collections.OrderedDict[str, HRTFTables] = collections.OrderedDict()
_TABLES_LOCK = threading.Lock()


def hrtf_tables(hrtf) -> HRTFTables:
    """The :class:`HRTFTables` of ``hrtf``: built on first use, then shared (keyed by the
    HRTF's ident; the :data:`HRTF_TABLES_KEPT` most recently used are kept)."""
    key = hrtf.ident
    with _TABLES_LOCK:
        tables = _TABLES.get(key)
        if tables is not None:
            _TABLES.move_to_end(key)
            return tables
    tables = HRTFTables(hrtf)  # outside the lock: building takes a while
    with _TABLES_LOCK:
        tables = _TABLES.setdefault(key, tables)
        _TABLES.move_to_end(key)
        while len(_TABLES) > HRTF_TABLES_KEPT:
            _TABLES.popitem(last=False)
    return tables


def clear_hrtf_tables() -> None:
    """Forget every cached :class:`HRTFTables` (frees their memory; the next renderer of
    each HRTF builds them again)."""
    with _TABLES_LOCK:
        _TABLES.clear()
