"""Head-related transfer function sets: SOFA files, the bundled MIT KEMAR, a rigid sphere.

An :class:`HRTF` holds head-related impulse responses (HRIRs) for ``D`` directions and two
ears, in the head frame of :mod:`acoustic_sim.frames` (x forward, y left, z up; receiver 0 is
the left ear). It is the quantity ``A_{l,r}(d, w)`` of the paper (Omura et al. 2022): the
spectra the SSDENet training data, the MUSIC steering vectors and the binaural renderer use.

Conventions shared by every set
-------------------------------
Amplitude
    An HRIR maps the free-field sound pressure at the head centre (head absent) to the
    pressure at the ear, so its magnitude tends to 1 (0 dB) at low frequencies, where the head
    is acoustically small. Measured sets include arbitrary loudspeaker and microphone gains,
    so data loaded from files are scaled once so that the diffuse-field (solid-angle weighted,
    direction-averaged) power of both ears over 200-400 Hz is 1.0. The analytic sphere obeys
    the convention by construction and is not rescaled.
Timing
    ``onset_samples`` is the (fractional) sample index within the HRIRs that corresponds to
    the arrival of the sound at the head centre: a renderer delays a source by its propagation
    time minus ``onset_samples``. For the sphere it is exact (the applied pre-delay); for
    measured sets it is the mean over directions of the mean left/right onset (see
    :meth:`HRTF.onsets`). Detected on band-limited responses, onsets fire a few samples
    before the wavefront's peak (on the sphere the estimate would come out ~8 samples below
    the exact value); all directions share that offset, so it shifts the absolute latency
    only, not ITDs or the timing of reflections relative to the direct sound. Every set is
    padded so that the earliest onset of any HRIR lies at least :data:`MIN_LEAD_SAMPLES`
    samples into the response (and a leading silence longer than 64 samples is trimmed).
Lookup
    ``mode="nearest"`` picks the measured direction with the largest dot product.
    ``mode="interpolated"`` interpolates barycentrically on the spherical Delaunay
    triangulation (the convex hull of the unit vectors) after aligning each HRIR on its own
    onset (magnitudes averaged separately), then re-applies the interpolated onsets as a
    fractional delay, so interpolating between directions with different ITDs does not
    comb-filter. Directions the set does not cover (:meth:`HRTF.covers`, e.g. below -40 deg
    for KEMAR) and directions in triangles that bridge a gap of the measurement grid fall
    back to the nearest direction.
"""

from __future__ import annotations

import functools
import hashlib
import math
import os
import warnings
from fractions import Fraction
from pathlib import Path

import numpy as np
from scipy import fft as sfft
from scipy import signal
from scipy.fft import next_fast_len
from scipy.spatial import ConvexHull, SphericalVoronoi, cKDTree

from acoustic_sim.acoustics import sofa_io
from acoustic_sim.errors import ConfigError, HRTFError
from acoustic_sim.files import atomic_path
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND, angle_between_deg, sph_to_vec, unit_vectors, vec_to_sph

ASSET_DIR = Path(__file__).resolve().parents[2] / "assets" / "hrtf"
"""Folder of the bundled HRTF data (``assets/hrtf`` in the repository)."""

KEMAR_PATH = ASSET_DIR / "mit_kemar_normal_pinna.sofa"
"""The bundled MIT KEMAR normal-pinna set (see ``assets/hrtf/README.md``)."""

MIN_LEAD_SAMPLES = 8
"""Minimum number of samples before the earliest onset of any HRIR of a set."""

ONSET_THRESHOLD_DB = -20.0
"""Onset = first crossing of this level (dB re the peak) by the 8x upsampled envelope of
the HRIR low-passed at 12 kHz (see ``_onsets``)."""

NORMALIZATION_BAND_HZ = (200.0, 400.0)
"""Band (Hz) over which the diffuse-field power of loaded data is scaled to 1.0."""

# Elevation rings of the MIT KEMAR measurement: (elevation deg, number of azimuths).
_KEMAR_RINGS = ((-40, 56), (-30, 60), (-20, 72), (-10, 72), (0, 72), (10, 72), (20, 72),
                (30, 60), (40, 56), (50, 45), (60, 36), (70, 24), (80, 12), (90, 1))
_UPSAMPLE = 8
_SAVED_IDENT_ATTR = "GLOBAL_AcousticSimIdent"
_SAVED_ONSET_ATTR = "GLOBAL_AcousticSimOnsetSamples"
_SAVED_SCALED_ATTR = "GLOBAL_AcousticSimAmplitude"
_SAVED_SCALED_VALUE = "free-field pressure at head centre to ear pressure"
_MODES = ("nearest", "interpolated")


def kemar_directions() -> np.ndarray:
    """The 710 MIT KEMAR measurement directions as unit vectors, shape (710, 3).

    Elevation rings every 10 deg from -40 to 90 deg, azimuths equally spaced from 0 deg
    (counter-clockwise) with the ring's count; the same order as the bundled SOFA file.
    """
    az = np.concatenate([np.arange(n) * 360.0 / n for _, n in _KEMAR_RINGS])
    el = np.concatenate([np.full(n, float(e)) for e, n in _KEMAR_RINGS])
    return sph_to_vec(az, el)




def _onsets(hrir: np.ndarray, sample_rate: float = SAMPLE_RATE) -> np.ndarray:
    """Onset (fractional samples) of each HRIR (..., K).

    The first crossing of :data:`ONSET_THRESHOLD_DB` re the peak by the envelope of the 8x
    upsampled response after a zero-phase raised-cosine low-pass (6 -> 12 kHz, capped below
    Nyquist). The low-pass keeps band-limiting ripples just before a sharp ipsilateral
    wavefront from crossing the threshold, which otherwise makes onsets (and ITDs) jump by
    a sample or two between neighbouring directions.
    """
    k = hrir.shape[-1]
    n = next_fast_len(k + 64)  # zero padding keeps the filter's circular wrap off the start
    rows = int(np.prod(hrir.shape[:-1]))
    # Responses in groups: the 8x upsampled analytic signals of all of KEMAR's 1420 took
    # 260 MB at once (the peak memory of every command that loads an HRTF); each row's
    # onset is computed alone either way.
    group = max(1, (16 << 20) // (16 * n * _UPSAMPLE))
    if rows > group:
        flat = np.asarray(hrir).reshape(rows, k)
        out = np.concatenate([_onsets(flat[i : i + group], sample_rate) for i in range(0, rows, group)])
        return out.reshape(hrir.shape[:-1])
    spec = sfft.rfft(hrir, n, axis=-1, workers=-1)
    freqs = np.fft.rfftfreq(n, 1.0 / sample_rate)
    cutoff = min(12_000.0, 0.9 * sample_rate / 2.0)
    ramp = np.clip((freqs - cutoff / 2.0) / (cutoff / 2.0), 0.0, 1.0)
    spec = spec * (0.5 + 0.5 * np.cos(np.pi * ramp))
    # Analytic signal upsampled by zero-padding the one-sided spectrum.
    analytic = np.zeros(hrir.shape[:-1] + (n * _UPSAMPLE,), dtype=complex)
    analytic[..., : spec.shape[-1]] = 2.0 * spec
    analytic[..., 0] = spec[..., 0]
    env = np.abs(sfft.ifft(analytic, axis=-1, workers=-1)[..., : k * _UPSAMPLE])
    thr = env.max(axis=-1, keepdims=True) * 10.0 ** (ONSET_THRESHOLD_DB / 20.0)
    i = np.argmax(env >= thr, axis=-1)
    # Linear interpolation of the crossing between samples i-1 and i of the envelope.
    prev = np.take_along_axis(env, np.maximum(i - 1, 0)[..., None], -1)[..., 0]
    cur = np.take_along_axis(env, i[..., None], -1)[..., 0]
    rise = np.where(cur > prev, cur - prev, 1.0)
    frac = np.where((i > 0) & (cur > prev), (thr[..., 0] - prev) / rise, 1.0)
    return np.clip(i - 1 + np.clip(frac, 0.0, 1.0), 0.0, None) / _UPSAMPLE


def _ident(sample_rate, directions: np.ndarray, hrir: np.ndarray) -> str:
    """First 16 hex digits of a sha256 over the sample rate, directions and HRIR bytes."""
    digest = hashlib.sha256()
    digest.update(str(round(float(sample_rate))).encode())
    digest.update((np.round(np.asarray(directions, dtype=float), 9) + 0.0).astype("<f8").tobytes())
    digest.update(np.ascontiguousarray(hrir, dtype="<f8").tobytes())
    return digest.hexdigest()[:16]


def _delay_spectra(spectra: np.ndarray, n_fft: int, delay) -> np.ndarray:
    """Multiply rFFT spectra (..., n_fft//2+1) by a (circular, fractional) delay in samples."""
    w = 2.0 * np.pi * np.arange(spectra.shape[-1]) / n_fft
    return spectra * np.exp(-1j * w * np.asarray(delay, dtype=float)[..., None])


# --------------------------------------------------------------------------------------
# Rigid sphere (Duda & Martens 1998)
# --------------------------------------------------------------------------------------


def sphere_transfer_function(radius, distance, cos_theta, freqs, *, c=SPEED_OF_SOUND,
                             threshold=1e-10) -> np.ndarray:
    """Pressure on a rigid sphere re free-field pressure at its centre (Duda & Martens 1998).

    The series solution for a point source at finite distance (their eqs. 1-2 and the
    appendix algorithm: recurrences for the spherical Hankel polynomials and the Legendre
    polynomials, terms added until two successive terms are below ``threshold`` relative to
    the sum). Vectorized: the frequency-only coefficients are computed for all frequencies
    at once, the sum over orders is a matrix product with the Legendre table.

    Parameters
    ----------
    radius : float
        Sphere radius in m, > 0.
    distance : float
        Source distance from the centre in m, > ``radius``.
    cos_theta : array_like, shape (X,)
        Cosine of the angle between the source direction and the ear's position vector.
    freqs : array_like, shape (F,)
        Frequencies in Hz, >= 0 (0 gives exactly 1).
    c : float
        Speed of sound in m/s.
    threshold : float
        Relative convergence threshold of the series.

    Returns
    -------
    numpy.ndarray, complex, shape (X, F)
        Transfer function with numpy's FFT sign convention (a delay tau is exp(-i w tau)):
        the ipsilateral ear leads the centre by about ``radius / c``.
    """
    x = np.asarray(cos_theta, dtype=float).ravel()
    f = np.asarray(freqs, dtype=float).ravel()
    rho = distance / radius
    out = np.ones((x.size, f.size), dtype=complex)
    pos = f > 0
    if not pos.any():
        return out
    mu = 2.0 * np.pi * f[pos] * radius / c
    with np.errstate(all="ignore"):
        zr = 1.0 / (1j * mu * rho)
        za = 1.0 / (1j * mu)
        qr2, qr1, qa2, qa1 = zr, zr * (1 - zr), za, za * (1 - za)
        coeffs = [zr / (za * (za - 1)), 3 * zr * (zr - 1) / (za * (2 * za**2 - 2 * za + 1))]
        # Convergence is judged on the x = 1 series (|P_m(x)| <= 1 bounds every other x).
        total = coeffs[0] + coeffs[1]
        old = np.ones(mu.size)
        new = np.abs(coeffs[1]) / np.abs(total)
        active = (old > threshold) | (new > threshold)
        m = 2
        while active.any():
            if m > 10_000:
                raise HRTFError("sphere series did not converge (radius/distance/frequency "
                                "out of range)")
            qr = -(2 * m - 1) * zr * qr1 + qr2
            qa = -(2 * m - 1) * za * qa1 + qa2
            term = np.where(active, (2 * m + 1) * qr / ((m + 1) * za * qa - qa1), 0.0)
            coeffs.append(term)
            total = total + term
            qr2, qr1, qa2, qa1 = qr1, qr, qa1, qa
            old, new = new, np.where(active, np.abs(term) / np.abs(total), 0.0)
            active &= (old > threshold) | (new > threshold)
            m += 1
    coeffs = np.array(coeffs)
    if not np.all(np.isfinite(coeffs)):
        raise HRTFError("sphere series overflowed (frequency too low for the recurrence)")
    legendre = np.empty((coeffs.shape[0], x.size))
    legendre[0] = 1.0
    legendre[1] = x
    for k in range(2, coeffs.shape[0]):
        legendre[k] = ((2 * k - 1) * x * legendre[k - 1] - (k - 1) * legendre[k - 2]) / k
    total = legendre.T @ coeffs.real + 1j * (legendre.T @ coeffs.imag)
    # Duda & Martens use the exp(+i w t) convention; conjugate for numpy's FFT.
    out[:, pos] = np.conj(rho * np.exp(-1j * mu) * total / (1j * mu))
    return out


@functools.lru_cache(maxsize=8)
def _spherical_cached(radius, distance, n_taps, sample_rate, directions_key):
    if directions_key is None:
        directions = kemar_directions()
    else:
        directions = np.frombuffer(directions_key, dtype=float).reshape(-1, 3)
    # Fixed pre-delay: the ipsilateral ear leads the centre by at most radius / c, and the
    # band-limited onset needs a few samples of room (8 at 44.1 kHz) on top of MIN_LEAD_SAMPLES.
    pre_delay = (math.ceil(radius * sample_rate / SPEED_OF_SOUND) + MIN_LEAD_SAMPLES
                 + math.ceil(8 * sample_rate / 44100))
    n_design = int(2 ** math.ceil(math.log2(max(4 * n_taps, 2048))))
    freqs = np.fft.rfftfreq(n_design, 1.0 / sample_rate)
    # Left ear at +y, right ear at -y: cos(theta) = +-y of the source direction.
    cos_theta = np.concatenate([directions[:, 1], -directions[:, 1]])
    tf = sphere_transfer_function(radius, distance, cos_theta, freqs)
    # Band-limit like an anti-aliasing filter (raised-cosine taper from 0.75 to 0.95 of
    # Nyquist): the sphere's response is not band-limited, and cutting it off at Nyquist
    # would ring across the whole response and blur the onsets.
    nyq = sample_rate / 2.0
    ramp = np.clip((freqs - 0.75 * nyq) / (0.2 * nyq), 0.0, 1.0)
    tf = tf * (0.5 + 0.5 * np.cos(np.pi * ramp))
    fade = max(n_taps // 16, 4)
    for _ in range(4):
        spec = _delay_spectra(tf, n_design, np.full(tf.shape[0], float(pre_delay)))
        h = np.fft.irfft(spec, n_design, axis=-1)[:, :n_taps]
        h[:, -fade:] *= 0.5 * (1.0 + np.cos(np.linspace(0.0, np.pi, fade)))
        onsets = _onsets(h, sample_rate)
        earliest = float(onsets.min())
        if earliest >= MIN_LEAD_SAMPLES:
            break
        pre_delay += math.ceil(MIN_LEAD_SAMPLES - earliest) + 1
    d = directions.shape[0]
    hrir = np.stack([h[:d], h[d:]], axis=1)
    hrtf = HRTF(hrir, directions, sample_rate, name="spherical", distance_m=distance,
                onset_samples=float(pre_delay),
                source=(f"rigid sphere, Duda & Martens 1998 (a = {radius} m, r = {distance} m, "
                        f"c = {SPEED_OF_SOUND} m/s)"))
    onsets = np.stack([onsets[:d], onsets[d:]], axis=1)
    onsets.flags.writeable = False
    hrtf._cache["onsets"] = onsets
    return hrtf


def _read_measurements(path: Path):
    """(sofa, Data.IR (M, 2, N) in the file's receiver order with Data.Delay applied,
    sample rate, unit directions (M, 3) in the head frame, distances (M,)), all checked."""
    sofa = sofa_io.read_sofa(path)
    convention = str(getattr(sofa, "GLOBAL_SOFAConventions", "") or "")
    if convention != "SimpleFreeFieldHRIR":
        hint = (" (frequency-domain data; convert it to SimpleFreeFieldHRIR first)"
                if "TF" in convention else "")
        raise HRTFError(f"{path}: SOFA convention {convention or 'missing'!r} is not supported"
                        f"{hint}; expected SimpleFreeFieldHRIR")
    ir = sofa_io.sofa_array(sofa, "Data_IR", path)
    if ir.ndim == 2:  # sofar drops a trailing singleton N
        ir = ir[:, :, None]
    if ir.ndim != 3 or ir.shape[0] == 0 or ir.shape[2] == 0:
        raise HRTFError(f"{path}: Data.IR has shape {ir.shape}, expected (M >= 1, 2, N >= 1)")
    if ir.shape[1] != 2:
        raise HRTFError(f"{path}: Data.IR has {ir.shape[1]} receivers, expected 2 (left, right)")
    m = ir.shape[0]
    fs = np.ravel(sofa_io.sofa_array(sofa, "Data_SamplingRate", path))
    if fs.size == 0 or not np.all(np.isfinite(fs)) or np.any(fs != fs[0]):
        raise HRTFError(f"{path}: Data.SamplingRate {fs} is not one finite value")
    fs = float(fs[0])
    if not 1000.0 <= fs <= 1_000_000.0:
        raise HRTFError(f"{path}: Data.SamplingRate {fs} Hz is out of range (1 kHz .. 1 MHz)")
    if not np.all(np.isfinite(ir)):
        raise HRTFError(f"{path}: Data.IR contains NaN or infinite values")
    pos = np.atleast_2d(sofa_io.sofa_array(sofa, "SourcePosition", path))
    if pos.shape != (m, 3):
        raise HRTFError(f"{path}: SourcePosition has shape {pos.shape}, expected ({m}, 3) to "
                        f"match Data.IR's {m} measurements")
    if not np.all(np.isfinite(pos)):
        raise HRTFError(f"{path}: SourcePosition contains NaN or infinite values")
    xyz = sofa_io.positions_to_cartesian(pos, getattr(sofa, "SourcePosition_Type", None),
                                  getattr(sofa, "SourcePosition_Units", None), path,
                                  "SourcePosition")
    dist = np.linalg.norm(xyz, axis=-1)
    if np.any(dist <= 0):
        raise HRTFError(f"{path}: a SourcePosition is at the listener (zero distance)")
    rot = sofa_io.listener_frame(sofa, path)
    if rot is not None:
        xyz = xyz @ rot.T
    directions = xyz / dist[:, None]
    delay = getattr(sofa, "Data_Delay", None)
    if delay is not None:
        delay = np.asarray(delay, dtype=float)
        if not np.all(np.isfinite(delay)) or np.any(delay < 0):
            raise HRTFError(f"{path}: Data.Delay must be finite and >= 0")
        if delay.size not in (2, 2 * m):
            raise HRTFError(f"{path}: Data.Delay has shape {delay.shape}, expected (1, 2) or ({m}, 2)")
        if np.any(delay != 0):
            delay = np.broadcast_to(delay.reshape(-1, 2), (m, 2))
            n = ir.shape[-1] + math.ceil(delay.max())
            ir = np.fft.irfft(_delay_spectra(np.fft.rfft(ir, n, axis=-1), n, delay), n, axis=-1)
    energy = np.sum(ir**2, axis=-1)
    if not np.any(energy > 0):
        raise HRTFError(f"{path}: Data.IR is all zeros")
    if np.any(energy == 0):
        bad = np.argwhere(energy == 0)[0]
        raise HRTFError(f"{path}: the HRIR of measurement {bad[0]}, receiver {bad[1]} is all zeros")
    return sofa, ir, fs, directions, dist


def sofa_left_receiver(path) -> int:
    """Index (0 or 1) of the left ear's receiver in a SOFA file, as :meth:`HRTF.load` reads
    it (same checks, warnings and errors): for code that hands the file to another reader."""
    path = Path(path)
    sofa, ir, _, directions, _ = _read_measurements(path)
    return sofa_io.left_receiver(sofa, ir, directions, path)


def _load_sofa(path: Path, sample_rate: int, name: str | None = None) -> HRTF:
    sofa, ir, fs, directions, dist = _read_measurements(path)
    m = ir.shape[0]
    # Which receiver is the left ear: ReceiverPosition checked against the data (it is
    # wrong in some public sets); Data.Delay above is in the file's receiver order.
    if sofa_io.left_receiver(sofa, ir, directions, path) == 1:
        ir = ir[:, ::-1, :]
    # Attributes written by HRTF.save_sofa are trusted only for the data they were written with.
    trusted = str(getattr(sofa, _SAVED_IDENT_ATTR, "")) == _ident(fs, directions, ir)
    # Duplicate directions (several azimuths at a pole, several distances) break the
    # triangulation; keep the first of each.
    _, first = np.unique(np.round(directions, 6), axis=0, return_index=True)
    if first.size < m:
        keep = np.sort(first)
        warnings.warn(f"{path}: dropped {m - keep.size} measurements whose direction repeats "
                      "an earlier one", stacklevel=3)
        ir, directions, dist = ir[keep], directions[keep], dist[keep]
    if round(fs) != sample_rate:
        ratio = Fraction(int(sample_rate)) / Fraction(fs).limit_denominator(1000)
        ir = signal.resample_poly(ir, ratio.numerator, ratio.denominator, axis=-1)
    onset, scaled = None, False
    if trusted and first.size == m:
        try:
            onset = float(getattr(sofa, _SAVED_ONSET_ATTR)) * sample_rate / fs
        except (AttributeError, TypeError, ValueError):
            onset = None
        if onset is not None and not (np.isfinite(onset) and 0.0 <= onset < ir.shape[-1]):
            onset = None
        scaled = str(getattr(sofa, _SAVED_SCALED_ATTR, "")) == _SAVED_SCALED_VALUE
    return HRTF._from_measurement(ir, directions, sample_rate, name=name or path.stem,
                                  distance_m=float(np.mean(dist)), source=str(path),
                                  onset_samples=onset, normalize=not scaled)


# --------------------------------------------------------------------------------------
# The HRTF set
# --------------------------------------------------------------------------------------


MUSASHI_RIGHT_PINNA_TILT_DEG = 10.0
"""Tilt (deg) of the robot's right pinna about the interaural axis, relative to the left.

Why the robot's ears are not mirror images: with mirror-symmetric ears (MIT KEMAR's
normal-pinna set is the left ear mirrored), every direction in the median plane gives
ILD = 0 and IPD = 0 at every frequency, so interaural features (the paper's only input to
SSDENet) cannot tell front from back or up from down there, and no network can. The
paper's robot discriminates top and bottom in the median plane (its Fig. 12e), which needs
interaural spectral differences: hand-mounted ear units (and human ears) are not exact
mirror images. 10 deg moves the right ear's pinna notch by about one KEMAR elevation step
(the notch runs 6.4-11.3 kHz over -40..90 deg), an asymmetry of the order that human pinnae
show in orientation."""


def tilted_right_pinna(base: HRTF, tilt_deg: float, *, name: str) -> HRTF:
    """``base`` with its right ear's pinna turned by ``tilt_deg`` about the interaural axis.

    The right ear hears direction ``d`` as ``base``'s right ear hears ``R_y(tilt) d``
    (``R_y`` a rotation about the head's y axis, the interaural axis: positive tilts the
    pinna's front edge down, so a source in front sounds to it as if higher, a source behind
    as if lower). A rotation about the interaural axis keeps each direction's lateral angle,
    and so the interaural time difference, while moving the pinna's spectral features along
    the cone of confusion. Right-ear responses come from :meth:`HRTF.hrirs_for` with
    ``mode="interpolated"`` (rotated directions below the base set's lowest elevation fall
    back to the nearest measured one); the left ear is unchanged. Directions are the base
    set's; the result is normalized like a loaded set.
    """
    if not np.isfinite(tilt_deg) or abs(tilt_deg) > 45.0:
        raise ConfigError(f"tilt_deg must be within +-45 deg, got {tilt_deg}")
    a = math.radians(float(tilt_deg))
    rot = np.array([[math.cos(a), 0.0, -math.sin(a)], [0.0, 1.0, 0.0], [math.sin(a), 0.0, math.cos(a)]])
    dirs = np.asarray(base.directions)
    right = base.hrirs_for(dirs @ rot.T, mode="interpolated")[:, 1]
    hrir = np.stack([np.asarray(base.hrir)[:, 0], right], axis=1)
    return HRTF._from_measurement(hrir, dirs, base.sample_rate, name=name, distance_m=base.distance_m,
                                  source=f"{base.source}; right pinna tilted {tilt_deg:g} deg about the interaural axis")


@functools.lru_cache(maxsize=4)
def _musashi(sample_rate: int) -> HRTF:
    return tilted_right_pinna(_load_sofa(KEMAR_PATH, sample_rate, name="kemar"), MUSASHI_RIGHT_PINNA_TILT_DEG, name="musashi")


class HRTF:
    """A set of head-related impulse responses on a set of directions (immutable).

    Build one with :meth:`load` (``"kemar"``, ``"spherical"`` or a SOFA path) or
    :meth:`spherical_head`; the constructor takes arrays already in this module's
    conventions (see the module docstring) and validates them.

    Parameters
    ----------
    hrir : array_like, shape (D, 2, K)
        Impulse responses, ``[:, 0]`` left ear, ``[:, 1]`` right ear; dimensionless (ear
        pressure per free-field pressure at the head centre), finite.
    directions : array_like, shape (D, 3)
        Source directions in the head frame (normalized here).
    sample_rate : int
        Sample rate in Hz, > 0.
    name : str
        Short name (``"kemar"``, ``"spherical"`` or the file stem).
    distance_m : float
        Source distance of the measurement in m, > 0.
    onset_samples : float, optional
        Sample index of the arrival at the head centre (see module docstring); estimated
        from the data when omitted.
    source : str
        Provenance (file path or description).

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
            onset_samples = float(np.mean(_onsets(hrir, int(sample_rate))))
        if not (np.isfinite(onset_samples) and 0 <= onset_samples < hrir.shape[2]):
            raise HRTFError(f"{name}: onset_samples {onset_samples} outside the response")
        az, el = vec_to_sph(dirs)
        for arr in (hrir, dirs, az, el):
            arr.flags.writeable = False
        d = self.__dict__
        d.update(name=str(name), sample_rate=int(sample_rate), hrir=hrir, directions=dirs,
                 azimuth_deg=az, elevation_deg=el, distance_m=float(distance_m),
                 onset_samples=float(onset_samples), source=str(source))
        d["ident"] = _ident(self.sample_rate, dirs, hrir)
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
            data win with a warning (see :func:`acoustic_sim.acoustics.sofa_io.left_receiver`);
            a non-zero ``Data.Delay`` is applied; directions that repeat an earlier one are dropped
            with a warning. Loaded data are scaled to unit diffuse-field power over
            200-400 Hz and padded so that every onset is >= 8 samples into the response.
        sample_rate : int
            Sample rate of the returned set in Hz (default 44100).

        Raises
        ------
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
            return _load_sofa(KEMAR_PATH, int(sample_rate), name="kemar")
        if isinstance(name_or_path, str) and name_or_path == "musashi":
            return _musashi(int(sample_rate))
        if not isinstance(name_or_path, (str, os.PathLike)):
            raise HRTFError(f"expected 'kemar', 'musashi', 'spherical' or a SOFA path, got {name_or_path!r}")
        path = Path(name_or_path)
        if isinstance(name_or_path, str) and not path.exists() and path.suffix == "" \
                and len(path.parts) == 1:
            raise HRTFError(f"unknown HRTF {name_or_path!r}: expected 'kemar', 'musashi', 'spherical' or "
                            "the path of a SimpleFreeFieldHRIR .sofa file")
        return _load_sofa(path, int(sample_rate))

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
            HRIR length in samples (default 512), >= 64.
        sample_rate : int
            Sample rate in Hz (default 44100).
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
        onsets = _onsets(ir, sample_rate)
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
        """Onset of each HRIR in samples (fractional), read-only (D, 2): the -20 dB crossing
        of the envelope of the 12 kHz low-passed, 8x upsampled response. The interaural
        time difference of direction d in seconds is ``(onsets[d, 1] - onsets[d, 0]) / fs``."""
        if "onsets" not in self._cache:
            on = _onsets(self.hrir, self.sample_rate)
            on.flags.writeable = False
            self._cache["onsets"] = on
        return self._cache["onsets"]

    def covers(self, vectors, *, tolerance_deg: float = 0.5) -> np.ndarray:
        """Whether directions (..., 3) lie inside the measured elevation range (+- tolerance)."""
        _, el = vec_to_sph(unit_vectors(vectors))
        return (el >= self.min_elevation_deg - tolerance_deg) & (
            el <= self.max_elevation_deg + tolerance_deg)

    # -- lookup -------------------------------------------------------------------------

    def _tree(self) -> cKDTree:
        if "tree" not in self._cache:
            self._cache["tree"] = cKDTree(self.directions)
        return self._cache["tree"]

    def nearest_index(self, vectors) -> np.ndarray:
        """Index of the measured direction closest in angle to each vector (..., 3) -> (...)."""
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
            spec = _delay_spectra(np.fft.rfft(self.hrir, n_fft, axis=-1), n_fft, -onsets)
            self._cache["aligned"] = (spec, onsets, n_fft)
        return self._cache["aligned"]

    def hrirs_for(self, vectors, *, mode: str = "nearest") -> np.ndarray:
        """HRIRs (..., 2, K) for direction vectors (..., 3) in the head frame.

        ``mode="nearest"`` returns the measured HRIR closest in angle; ``"interpolated"``
        interpolates onset-aligned HRIRs barycentrically on the Delaunay triangulation (the
        weighted mean of the aligned spectra, its magnitude replaced by the weighted mean of
        the magnitudes) and re-applies the interpolated onsets as a fractional delay. It
        falls back to nearest outside :meth:`covers` and in triangles that bridge a gap of
        the grid (edges longer than 3x the median nearest-neighbour angle). At a measured
        direction both modes return the measured HRIR. Above about 8 kHz, where pinna
        notches move by more than their width between neighbouring KEMAR directions, no
        interpolation of measured responses is exact; there the result can be up to ~10 dB
        off in narrow bands (leave-one-out on KEMAR's 5 deg horizontal ring: median
        log-spectral distance 0.8 dB over 0.3-12 kHz).
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
                h = np.fft.irfft(_delay_spectra(mixed, n_fft, onset), n_fft, axis=-1)
                out[ok] = h[..., : self.n_taps]
        return out.reshape(shape + (2, self.n_taps))

    def hrir_at(self, azimuth_deg: float, elevation_deg: float, *, mode: str = "nearest") -> np.ndarray:
        """HRIR pair (2, K) for one direction given in degrees (azimuth left positive)."""
        return self.hrirs_for(sph_to_vec(azimuth_deg, elevation_deg), mode=mode)

    # -- spectra ------------------------------------------------------------------------

    def _check_nfft(self, n_fft, bins):
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
        """Transfer functions A_{l,r}(d, w) of all measured directions, complex (D, 2, n_bins).

        The rFFT of each HRIR zero-padded to ``n_fft`` (>= K); ``bins`` selects rFFT bins
        (default all ``n_fft // 2 + 1``). Bin ``k`` is ``k * sample_rate / n_fft`` Hz.
        Cached per ``n_fft``; without ``bins`` the shared, read-only cache is returned.
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
        """Transfer functions complex (..., 2, n_bins) for directions given either as vectors
        (..., 3) or as ``azimuth_deg`` / ``elevation_deg`` arrays (degrees, broadcast)."""
        sel = self._check_nfft(n_fft, bins)
        if (vectors is None) == (azimuth_deg is None or elevation_deg is None):
            raise ConfigError("give either vectors or both azimuth_deg and elevation_deg")
        v = unit_vectors(vectors) if vectors is not None else sph_to_vec(azimuth_deg, elevation_deg)
        if mode == "nearest":
            return self.spectra(n_fft)[self.nearest_index(v)][..., sel]
        return np.fft.rfft(self.hrirs_for(v, mode=mode), int(n_fft), axis=-1)[..., sel]

    # -- diffuse field ------------------------------------------------------------------

    def solid_angle_weights(self) -> np.ndarray:
        """Weights (D,) summing to 1: each direction's spherical Voronoi cell area, restricted
        to the covered band (elevation range +- half the largest nearest-neighbour angle)."""
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
        """Direction-averaged power sum_d w_d |A_{l,r}(d, w)|^2 per ear, real (2, n_bins),
        with the solid-angle weights of :meth:`solid_angle_weights`."""
        w = self.solid_angle_weights()
        return np.einsum("d,dek->ek", w, np.abs(self.spectra(n_fft)) ** 2)

    def diffuse_field_coherence(self, n_fft: int = 2048) -> np.ndarray:
        """Real interaural coherence of a diffuse field, (n_bins,), in -1..1.

        ``Re(sum_d w_d A_l A_r*) / sqrt(P_l P_r)`` with the solid-angle weights; 1 at DC.
        """
        w = self.solid_angle_weights()
        spec = self.spectra(n_fft)
        cross = np.einsum("d,dk->k", w, spec[:, 0] * np.conj(spec[:, 1])).real
        p = self.diffuse_field_power(n_fft)
        denom = np.sqrt(p[0] * p[1])
        return np.divide(cross, denom, out=np.zeros_like(cross), where=denom > 0)

    # -- writing ------------------------------------------------------------------------

    def save_sofa(self, path) -> Path:
        """Write the set as a SimpleFreeFieldHRIR SOFA file (``load`` reads it back unchanged:
        same HRIRs, directions, onset and ident). Written atomically; returns the path."""
        import sofar

        path = Path(path)
        sofa = sofar.Sofa("SimpleFreeFieldHRIR")
        sofa.Data_IR = self.hrir
        sofa.Data_SamplingRate = float(self.sample_rate)
        sofa.Data_Delay = np.zeros((1, 2))
        sofa.SourcePosition = np.column_stack(
            [self.azimuth_deg % 360.0, self.elevation_deg, np.full(self.n_directions, self.distance_m)])
        sofa.SourcePosition_Type = "spherical"
        sofa.SourcePosition_Units = "degree, degree, metre"
        sofa.ReceiverPosition = np.array([[0.0, 0.09, 0.0], [0.0, -0.09, 0.0]])
        sofa.GLOBAL_Title = f"acoustic-sim HRTF {self.name}"
        sofa.GLOBAL_Comment = (f"Written by acoustic_sim.acoustics.hrtf (ident {self.ident}); "
                               f"source: {self.source}")
        sofa.add_attribute(_SAVED_IDENT_ATTR, self.ident)
        sofa.add_attribute(_SAVED_ONSET_ATTR, repr(self.onset_samples))
        sofa.add_attribute(_SAVED_SCALED_ATTR, _SAVED_SCALED_VALUE)
        with atomic_path(path) as tmp:
            try:
                sofar.write_sofa(str(tmp), sofa, compression=4)
            except Exception as exc:
                raise HRTFError(f"cannot write SOFA file {path}: {exc}") from exc
        return path
