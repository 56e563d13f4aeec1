"""The HRTF set: :class:`HRTF`, its constructors (``load`` by name or SOFA file, the rigid
sphere) and its basic properties; lookups, spectra and diffuse-field statistics come from its
base classes (:mod:`~acoustic_sim.acoustics.hrtf.hrir_lookup`,
:mod:`~acoustic_sim.acoustics.hrtf.transfer_functions`,
:mod:`~acoustic_sim.acoustics.hrtf.diffuse_field`). Conventions: :mod:`acoustic_sim.acoustics.hrtf`.
"""

from __future__ import annotations

import functools
import math
import os
from pathlib import Path

import numpy as np

from acoustic_sim.acoustics.hrtf.diffuse_field import DiffuseField
from acoustic_sim.acoustics.hrtf.hrir_lookup import HRIRLookup
from acoustic_sim.acoustics.hrtf.kemar import KEMAR_PATH, kemar_directions
from acoustic_sim.acoustics.hrtf.pinna import MUSASHI_RIGHT_PINNA_TILT_DEG, tilted_right_pinna
from acoustic_sim.acoustics.hrtf.responses import MIN_LEAD_SAMPLES, detect_onsets, hrir_ident
from acoustic_sim.acoustics.hrtf.sofa_read import LoadedSet, load_sofa
from acoustic_sim.acoustics.hrtf.sofa_write import write_sofa
from acoustic_sim.acoustics.hrtf.sphere import sphere_responses
from acoustic_sim.acoustics.hrtf.transfer_functions import TransferFunctions
from acoustic_sim.errors import ConfigError, HRTFError
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND, unit_vectors, vec_to_sph

NORMALIZATION_BAND_HZ = (200.0, 400.0)
"""Band (Hz) over which the diffuse-field power of loaded data is scaled to 1.0."""


class HRTF(HRIRLookup, TransferFunctions, DiffuseField):
    """A set of head-related impulse responses on a set of directions (immutable).

    Build one with :meth:`load` (``"kemar"``, ``"spherical"`` or a SOFA path) or
    :meth:`spherical_head`; the constructor takes arrays already in the package's
    conventions (see :mod:`acoustic_sim.acoustics.hrtf`) and validates them.

    Parameters
    ----------
    hrir : array_like, shape (D, 2, K)
        Impulse responses, ``[:, 0]`` left ear, ``[:, 1]`` right ear; dimensionless (ear
        pressure per free-field pressure at the head centre), finite.
    directions : array_like, shape (D, 3)
        Source directions in the head frame, non-zero and finite (normalized here).
    sample_rate : int
        Sample rate in Hz, > 0.
    name : str
        Short name (``"kemar"``, ``"spherical"`` or the file stem).
    distance_m : float
        Source distance of the measurement in m, > 0.
    onset_samples : float, optional
        Sample index of the arrival at the head centre (see the package docstring),
        0 <= onset < K; estimated from the data when omitted.
    source : str
        Provenance (file path or description).

    Raises
    ------
    HRTFError
        A wrong shape, non-finite values, or an out-of-range rate, distance or onset.

    Attributes
    ----------
    name, ident, sample_rate, hrir, directions, azimuth_deg, elevation_deg, distance_m,
    onset_samples, source
        ``ident`` is the first 16 hex digits of a sha256 over the sample rate, the directions
        and the HRIR bytes: checkpoints store it to refuse a mismatched HRTF.
    """

    def __init__(self, hrir, directions, sample_rate, *, name="custom", distance_m=1.0,
                 onset_samples=None, source=""):
        hrir = np.array(hrir, dtype=np.float64)
        if hrir.ndim != 3 or hrir.shape[1] != 2 or hrir.shape[0] < 1 or hrir.shape[2] < 1:
            raise HRTFError(f"{name}: hrir must have shape (D >= 1, 2, K >= 1), got {hrir.shape}")
        if not np.all(np.isfinite(hrir)):
            raise HRTFError(f"{name}: hrir contains NaN or infinite values")
        try:
            dirs = unit_vectors(directions, f"{name}: directions")
        except ConfigError as exc:
            raise HRTFError(str(exc)) from None
        if dirs.shape != (hrir.shape[0], 3):
            raise HRTFError(f"{name}: directions have shape {dirs.shape}, expected "
                            f"({hrir.shape[0]}, 3)")
        if not (isinstance(sample_rate, (int, np.integer)) or float(sample_rate).is_integer()) \
                or int(sample_rate) <= 0:
            raise HRTFError(f"{name}: sample_rate must be a positive integer (Hz), got {sample_rate}")
        if not (np.isfinite(distance_m) and distance_m > 0):
            raise HRTFError(f"{name}: distance_m must be finite and > 0, got {distance_m}")
        if onset_samples is None:
            onset_samples = float(np.mean(detect_onsets(hrir, int(sample_rate))))
        if not (np.isfinite(onset_samples) and 0 <= onset_samples < hrir.shape[2]):
            raise HRTFError(f"{name}: onset_samples {onset_samples} outside the response")
        az, el = vec_to_sph(dirs)
        for arr in (hrir, dirs, az, el):
            arr.flags.writeable = False
        d = self.__dict__
        d.update(name=str(name), sample_rate=int(sample_rate), hrir=hrir, directions=dirs,
                 azimuth_deg=az, elevation_deg=el, distance_m=float(distance_m),
                 onset_samples=float(onset_samples), source=str(source))
        d["ident"] = hrir_ident(self.sample_rate, dirs, hrir)
        d["_cache"] = {}

    def __setattr__(self, name, value):
        raise AttributeError(f"HRTF is immutable (tried to set {name!r})")

    def __repr__(self):
        return (f"HRTF(name={self.name!r}, D={self.n_directions}, K={self.n_taps}, "
                f"fs={self.sample_rate}, ident={self.ident})")

    # -- construction -----------------------------------------------------------------

    @classmethod
    def load(cls, name_or_path, *, sample_rate: int = SAMPLE_RATE) -> HRTF:
        """Load an HRTF set by name or from a SimpleFreeFieldHRIR SOFA file.

        Parameters
        ----------
        name_or_path : str or os.PathLike
            ``"kemar"`` (the bundled MIT KEMAR normal-pinna set, 710 directions, elevation
            -40..90 deg), ``"musashi"`` (the robot's ears: KEMAR with the right pinna tilted
            by :data:`MUSASHI_RIGHT_PINNA_TILT_DEG`, see :func:`tilted_right_pinna`),
            ``"spherical"`` (:meth:`spherical_head` with defaults) or the path of
            a SOFA file. Files may use any sample rate (resampled with
            :func:`scipy.signal.resample_poly`), any number of directions, spherical or
            cartesian ``SourcePosition``; the receiver with the larger y in
            ``ReceiverPosition`` is the left ear (receiver 0 in files of the ARI SOFA API
            for Matlab/Octave <= 1.1.0, which mirrored the positions), checked against the
            data: where the ear facing the most lateral sources is not the louder one, the
            data win with a warning (see
            :func:`acoustic_sim.acoustics.hrtf.sofa_geometry.left_receiver`);
            a non-zero ``Data.Delay`` is applied; directions that repeat an earlier one are dropped
            with a warning. Loaded data are scaled to unit diffuse-field power over
            200-400 Hz and padded so that every onset is >= 8 samples into the response.
        sample_rate : int
            Sample rate of the returned set in Hz, > 0 (default 44100).

        Returns
        -------
        HRTF
            The set: HRIRs (D, 2, K) on D directions (710 for KEMAR and the sphere).

        Raises
        ------
        ConfigError
            ``sample_rate`` is not a positive integer.
        HRTFError
            The file does not exist, is not a readable SimpleFreeFieldHRIR SOFA file, its
            content is malformed, or neither ``ReceiverPosition`` nor the data tell which
            receiver is the left ear (the message names the file and the problem).
        """
        if not isinstance(sample_rate, (int, np.integer)) or sample_rate <= 0:
            raise ConfigError(f"sample_rate must be a positive integer in Hz, got {sample_rate!r}")
        if isinstance(name_or_path, str) and name_or_path == "spherical":
            return cls.spherical_head(sample_rate=int(sample_rate))
        if isinstance(name_or_path, str) and name_or_path == "kemar":
            return cls._from_file(load_sofa(KEMAR_PATH, int(sample_rate), name="kemar"))
        if isinstance(name_or_path, str) and name_or_path == "musashi":
            return _musashi(int(sample_rate))
        if not isinstance(name_or_path, (str, os.PathLike)):
            raise HRTFError(f"expected 'kemar', 'musashi', 'spherical' or a SOFA path, got {name_or_path!r}")
        path = Path(name_or_path)
        if isinstance(name_or_path, str) and not path.exists() and path.suffix == "" \
                and len(path.parts) == 1:
            raise HRTFError(f"unknown HRTF {name_or_path!r}: expected 'kemar', 'musashi', 'spherical' or "
                            "the path of a SimpleFreeFieldHRIR .sofa file")
        return cls._from_file(load_sofa(path, int(sample_rate)))

    @staticmethod
    def spherical_head(radius: float = 0.0875, *, directions=None, distance: float = 1.5,
                       n_taps: int = 512, sample_rate: int = SAMPLE_RATE) -> HRTF:
        """Rigid-sphere head without pinnae (Duda & Martens 1998), ears at +-90 deg azimuth.

        The series solution for a point source at ``distance`` is evaluated on a dense
        frequency grid (at least 2048-point FFT), the free-field delay to the centre is
        removed by the normalization of the solution, a fixed pre-delay of
        ``ceil(radius * fs / c) + 8 + ceil(8 fs / 44100)`` samples is applied (28 at the
        defaults, so the ipsilateral onset lands >= 8 samples in), the spectrum is tapered
        to zero between 0.75 and 0.95 of Nyquist (like an anti-aliasing filter), and the
        real, causal HRIR is cut to ``n_taps`` with a half-Hann fade-out over the last
        ``n_taps // 16`` samples. ``onset_samples`` equals the pre-delay exactly. Results
        are cached per argument set (the returned object is shared; it is immutable).

        Parameters
        ----------
        radius : float
            Head radius in m (default 0.0875), > 0.
        directions : array_like, shape (D, 3), optional
            Source directions; default: the 710 MIT KEMAR directions
            (:func:`kemar_directions`).
        distance : float
            Source distance from the head centre in m (default 1.5), > ``radius``.
        n_taps : int
            HRIR length in samples (default 512), >= 64 and more than twice
            ``ceil(radius * fs / c) + 24``.
        sample_rate : int
            Sample rate in Hz, > 0 (default 44100).

        Returns
        -------
        HRTF
            The set, named ``"spherical"``: HRIRs (D, 2, n_taps).

        Raises
        ------
        ConfigError
            An argument out of range.
        """
        if not (np.isfinite(radius) and radius > 0):
            raise ConfigError(f"radius must be > 0 m, got {radius}")
        if not (np.isfinite(distance) and distance > radius):
            raise ConfigError(f"distance must exceed the radius ({radius} m), got {distance}")
        if not isinstance(n_taps, (int, np.integer)) or n_taps < 64:
            raise ConfigError(f"n_taps must be an integer >= 64, got {n_taps!r}")
        if not isinstance(sample_rate, (int, np.integer)) or sample_rate <= 0:
            raise ConfigError(f"sample_rate must be a positive integer in Hz, got {sample_rate!r}")
        if math.ceil(radius * sample_rate / SPEED_OF_SOUND) + MIN_LEAD_SAMPLES + 16 >= n_taps // 2:
            raise ConfigError(f"n_taps={n_taps} is too short for a {radius} m head")
        key = None if directions is None else np.ascontiguousarray(unit_vectors(directions)).tobytes()
        return _spherical_cached(float(radius), float(distance), int(n_taps), int(sample_rate), key)

    @classmethod
    def _from_measurement(cls, ir, directions, sample_rate, *, name, distance_m, source,
                          onset_samples=None, normalize=True) -> HRTF:
        """Pad/trim the lead to >= MIN_LEAD_SAMPLES, scale to unit diffuse-field power."""
        onsets = detect_onsets(ir, sample_rate)
        earliest = float(onsets.min())
        shift = 0
        if earliest < MIN_LEAD_SAMPLES:
            shift = math.ceil(MIN_LEAD_SAMPLES - earliest) + 2
            ir = np.concatenate([np.zeros(ir.shape[:2] + (shift,)), ir], axis=-1)
        elif earliest > 8 * MIN_LEAD_SAMPLES:  # drop a long leading silence
            shift = -math.floor(earliest - 2 * MIN_LEAD_SAMPLES)
            ir = ir[..., -shift:]
        onset = float(np.mean(onsets)) if onset_samples is None else float(onset_samples)
        hrtf = cls(ir, directions, sample_rate, name=name, distance_m=distance_m,
                   onset_samples=onset + shift, source=source)
        onsets = onsets + shift
        onsets.flags.writeable = False
        hrtf._cache["onsets"] = onsets
        if normalize:
            n_fft = max(4096, 1 << (hrtf.n_taps - 1).bit_length())
            freqs = np.fft.rfftfreq(n_fft, 1.0 / sample_rate)
            band = (freqs >= NORMALIZATION_BAND_HZ[0]) & (freqs <= NORMALIZATION_BAND_HZ[1])
            power = float(np.mean(hrtf.diffuse_field_power(n_fft)[:, band]))
            if not (np.isfinite(power) and power > 0):
                raise HRTFError(f"{source}: no energy in {NORMALIZATION_BAND_HZ} Hz to normalize")
            gain = 1.0 / math.sqrt(power)
            onsets = hrtf._cache["onsets"]
            hrtf = cls(hrtf.hrir * gain, hrtf.directions, sample_rate, name=name,
                       distance_m=distance_m, onset_samples=hrtf.onset_samples, source=source)
            hrtf._cache["normalization_gain"] = gain
            hrtf._cache["onsets"] = onsets
        return hrtf

    # -- basic properties ---------------------------------------------------------------

    @property
    def n_directions(self) -> int:
        """Number of directions D."""
        return self.hrir.shape[0]

    @property
    def n_taps(self) -> int:
        """HRIR length K in samples."""
        return self.hrir.shape[2]

    @property
    def min_elevation_deg(self) -> float:
        """Lowest measured elevation in deg."""
        return float(self.elevation_deg.min())

    @property
    def max_elevation_deg(self) -> float:
        """Highest measured elevation in deg."""
        return float(self.elevation_deg.max())

    @property
    def normalization_gain(self) -> float:
        """Factor applied to the file's data by the diffuse-field normalization (1.0 if none)."""
        return float(self._cache.get("normalization_gain", 1.0))

    def onsets(self) -> np.ndarray:
        """Onset of each HRIR: the -20 dB crossing of the envelope of the 12 kHz low-passed,
        8x upsampled response (:func:`~acoustic_sim.acoustics.hrtf.responses.detect_onsets`).

        Returns
        -------
        numpy.ndarray, float, shape (D, 2)
            Onsets in fractional samples, 0..K, read-only. The interaural time difference
            of direction d in seconds is ``(onsets[d, 1] - onsets[d, 0]) / fs``.
        """
        if "onsets" not in self._cache:
            on = detect_onsets(self.hrir, self.sample_rate)
            on.flags.writeable = False
            self._cache["onsets"] = on
        return self._cache["onsets"]

    def covers(self, vectors, *, tolerance_deg: float = 0.5) -> np.ndarray:
        """Whether directions lie inside the measured elevation range.

        Parameters
        ----------
        vectors : array_like, shape (..., 3)
            Directions in the head frame, non-zero and finite.
        tolerance_deg : float
            Margin in degrees beyond the lowest and highest elevation, >= 0 (default 0.5).

        Returns
        -------
        numpy.ndarray, bool, shape (...)
        """
        _, el = vec_to_sph(unit_vectors(vectors))
        return (el >= self.min_elevation_deg - tolerance_deg) & (
            el <= self.max_elevation_deg + tolerance_deg)

    @classmethod
    def _from_file(cls, loaded: LoadedSet) -> HRTF:
        """The set of a SOFA file's arrays (:func:`~acoustic_sim.acoustics.hrtf.sofa_read.load_sofa`)."""
        return cls._from_measurement(loaded.hrir, loaded.directions, loaded.sample_rate, name=loaded.name,
                                     distance_m=loaded.distance_m, source=loaded.source,
                                     onset_samples=loaded.onset_samples, normalize=not loaded.scaled)

    # -- writing ------------------------------------------------------------------------

    def save_sofa(self, path) -> Path:
        """Write the set as a SimpleFreeFieldHRIR SOFA file, atomically; :meth:`load` reads it
        back unchanged (same HRIRs, directions, onset and ident).

        Parameters
        ----------
        path : str or os.PathLike
            Target file with the suffix ``.sofa`` (sofar swaps any other for ``.sofa``, and
            the write fails); missing folders are created.

        Returns
        -------
        pathlib.Path
            ``path``.

        Raises
        ------
        HRTFError
            sofar cannot write the file.
        ConfigError
            The path is a folder or not writable.
        """
        return write_sofa(self, path)


@functools.lru_cache(maxsize=8)
def _spherical_cached(radius, distance, n_taps, sample_rate, directions_key):
    if directions_key is None:
        directions = kemar_directions()
    else:
        directions = np.frombuffer(directions_key, dtype=float).reshape(-1, 3)
    sphere = sphere_responses(radius, distance, n_taps, sample_rate, directions)
    hrtf = HRTF(sphere.hrir, directions, sample_rate, name="spherical", distance_m=distance,
                onset_samples=sphere.onset_samples, source=sphere.source)
    hrtf._cache["onsets"] = sphere.onsets
    return hrtf


@functools.lru_cache(maxsize=4)
def _musashi(sample_rate: int) -> HRTF:
    kemar = HRTF._from_file(load_sofa(KEMAR_PATH, sample_rate, name="kemar"))
    return tilted_right_pinna(kemar, MUSASHI_RIGHT_PINNA_TILT_DEG, name="musashi")
