"""The rigid-sphere head without pinnae (Duda & Martens 1998): its transfer function and
the HRIRs :meth:`~acoustic_sim.acoustics.hrtf.HRTF.spherical_head` builds from it."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from acoustic_sim.acoustics.hrtf.responses import MIN_LEAD_SAMPLES, delay_spectra, detect_onsets
from acoustic_sim.errors import HRTFError
from acoustic_sim.frames import SPEED_OF_SOUND


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
        Cosine of the angle between the source direction and the ear's position vector,
        -1..1 (dimensionless).
    freqs : array_like, shape (F,)
        Frequencies in Hz, >= 0 (0 gives exactly 1).
    c : float
        Speed of sound in m/s, > 0 (default 343).
    threshold : float
        Relative convergence threshold of the series, > 0 (default 1e-10).

    Returns
    -------
    numpy.ndarray, complex, shape (X, F)
        Transfer function with numpy's FFT sign convention (a delay tau is exp(-i w tau)):
        the ipsilateral ear leads the centre by about ``radius / c``.

    Raises
    ------
    HRTFError
        The series does not converge within 10000 terms or overflows.
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


class SphereResponses(NamedTuple):
    """HRIRs of the rigid sphere, in the HRTF conventions (see :func:`sphere_responses`)."""

    hrir: np.ndarray
    """Impulse responses, shape (D, 2, n_taps), left ear first."""
    onset_samples: float
    """The applied pre-delay in samples: the exact arrival at the head centre."""
    onsets: np.ndarray
    """Detected onset of each response in samples, shape (D, 2), read-only."""
    source: str
    """Provenance (the model and its parameters)."""


def sphere_responses(radius: float, distance: float, n_taps: int, sample_rate: int,
                     directions: np.ndarray) -> SphereResponses:
    """HRIRs of a rigid sphere with ears at +-90 deg azimuth (the design of
    :meth:`~acoustic_sim.acoustics.hrtf.HRTF.spherical_head`, which checks the arguments).

    Parameters
    ----------
    radius : float
        Head radius in m, > 0.
    distance : float
        Source distance from the head centre in m, > ``radius``.
    n_taps : int
        HRIR length in samples, >= 64 and long enough for the head (see ``spherical_head``).
    sample_rate : int
        Sample rate in Hz, > 0.
    directions : numpy.ndarray, shape (D, 3)
        Unit source directions in the head frame.

    Returns
    -------
    SphereResponses
        ``hrir`` (D, 2, n_taps), ``onset_samples``, ``onsets`` (D, 2) and ``source``.
    """
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
        spec = delay_spectra(tf, n_design, np.full(tf.shape[0], float(pre_delay)))
        h = np.fft.irfft(spec, n_design, axis=-1)[:, :n_taps]
        h[:, -fade:] *= 0.5 * (1.0 + np.cos(np.linspace(0.0, np.pi, fade)))
        onsets = detect_onsets(h, sample_rate)
        earliest = float(onsets.min())
        if earliest >= MIN_LEAD_SAMPLES:
            break
        pre_delay += math.ceil(MIN_LEAD_SAMPLES - earliest) + 1
    d = directions.shape[0]
    hrir = np.stack([h[:d], h[d:]], axis=1)
    onsets = np.stack([onsets[:d], onsets[d:]], axis=1)
    onsets.flags.writeable = False
    source = (f"rigid sphere, Duda & Martens 1998 (a = {radius} m, r = {distance} m, "
              f"c = {SPEED_OF_SOUND} m/s)")
    return SphereResponses(hrir=hrir, onset_samples=float(pre_delay), onsets=onsets, source=source)
