"""The ear unit's microphone and ADC: pressure at the eardrum to digital samples.

Models the paper's microphone board (Table 1): an ICS-40619 MEMS microphone (sensitivity
-38 dBV/Pa, SNR 67 dBA re 94 dB SPL, i.e. 27 dBA equivalent input noise, acoustic overload
at 132 dB SPL, flat 20 Hz-20 kHz with a first-order high-pass at its low corner) feeding an
ADS1271 24-bit delta-sigma ADC.

Digital full scale (1.0) is set at the microphone's overload point: the peak of a 132 dB
SPL sine. That is the scale of every audio WAV the project writes and reads, so
``full_scale_pa`` converts back to pascal.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import signal

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, db_spl_to_pa


@dataclasses.dataclass(frozen=True, kw_only=True)
class MicrophoneSpec:
    """Microphone and ADC parameters.

    Parameters
    ----------
    sensitivity_dbv : float
        Output voltage for 1 Pa (94 dB SPL), dBV/Pa; ICS-40619: -38.
    snr_dba : float
        Signal-to-noise ratio re 94 dB SPL, A-weighted, dB; ICS-40619: 67.
    overload_db_spl : float
        Acoustic overload point (dB SPL, RMS of a sine); ICS-40619: 132.
    highpass_hz : float
        Low-frequency corner (Hz) of the first-order high-pass, 1-200.
    adc_bits : int
        ADC resolution; ADS1271: 24.
    """

    sensitivity_dbv: float = -38.0
    snr_dba: float = 67.0
    overload_db_spl: float = 132.0
    highpass_hz: float = 20.0
    adc_bits: int = 24

    def __post_init__(self) -> None:
        if not 0 < self.snr_dba < 140:
            raise ConfigError(f"snr_dba must be 0..140 dB, got {self.snr_dba}")
        if not 80 <= self.overload_db_spl <= 180:
            raise ConfigError(f"overload_db_spl must be 80..180 dB SPL, got {self.overload_db_spl}")
        if not 1 <= self.highpass_hz <= 200:
            raise ConfigError(f"highpass_hz must be 1..200 Hz, got {self.highpass_hz}")
        if not 8 <= self.adc_bits <= 32:
            raise ConfigError(f"adc_bits must be 8..32, got {self.adc_bits}")

    @property
    def full_scale_pa(self) -> float:
        """Pressure (Pa) at digital full scale: the peak of a sine at the overload point."""
        return float(db_spl_to_pa(self.overload_db_spl) * np.sqrt(2.0))

    @property
    def self_noise_pa(self) -> float:
        """Equivalent input noise (Pa RMS, A-weighted) = 94 dB SPL - SNR."""
        return float(db_spl_to_pa(94.0 - self.snr_dba))


def _compiled_lfilter():
    """scipy.signal.lfilter's compiled kernel, which its Python wrapper (array-API
    dispatch, validation, copies) reaches after about 15 us per call; the microphone
    filters every 16 ms block. None (use lfilter) unless this SciPy has it, callable as
    lfilter calls it, with lfilter's result (checked here, once)."""
    try:
        from scipy.signal._sigtools import _linear_filter

        b, a = signal.butter(1, 0.01, "high")
        x = np.random.default_rng(0).standard_normal((2, 16))
        zi = np.full((2, 1), 0.5)
        out, zf = _linear_filter(b, a, x, -1, zi)
        ref, ref_zf = signal.lfilter(b, a, x, axis=-1, zi=zi)
        if np.allclose(out, ref) and np.allclose(zf, ref_zf):
            return _linear_filter
    except Exception:  # noqa: BLE001 - any surprise means: use the public API
        return None
    return None


_LINEAR_FILTER = _compiled_lfilter()


FULL_SCALE_PA = MicrophoneSpec().full_scale_pa
"""Pascal per unit of the project's WAV files (the default microphone's full scale)."""


def a_weighting_power_gain(sample_rate: int = SAMPLE_RATE) -> float:
    """Power gain of IEC 61672 A-weighting for white noise band-limited to Nyquist."""
    f = np.linspace(10.0, sample_rate / 2, 20000)
    f2 = f**2
    ra = (12194.0**2 * f2**2) / ((f2 + 20.6**2) * np.sqrt((f2 + 107.7**2) * (f2 + 737.9**2)) * (f2 + 12194.0**2))
    ra *= 10 ** (2.0 / 20)  # normalize to 0 dB at 1 kHz
    return float(np.mean(ra**2))


class Microphone:
    """Stream both ears' pressure through the microphone and ADC model.

    Parameters
    ----------
    spec : MicrophoneSpec
    rng : numpy.random.Generator
        Draws the self-noise (independent per ear).
    sample_rate : int
        Hz.
    """

    def __init__(self, spec: MicrophoneSpec | None = None, *, rng: np.random.Generator, sample_rate: int = SAMPLE_RATE) -> None:
        self.spec = spec or MicrophoneSpec()
        self.rng = rng
        self.sample_rate = sample_rate
        self.b, self.a = signal.butter(1, self.spec.highpass_hz, "high", fs=sample_rate)
        self.zi = np.zeros((2, 1))
        # White self-noise whose A-weighted level is 94 - SNR dB SPL.
        self.noise_rms = self.spec.self_noise_pa / np.sqrt(a_weighting_power_gain(sample_rate))
        self.levels = 2 ** (self.spec.adc_bits - 1)
        self._to_codes = self.levels / self.spec.full_scale_pa  # ADC codes per pascal
        self._lsb = np.float32(1.0 / self.levels)  # full scale per code (a power of two)

    def __call__(self, pressure: np.ndarray) -> np.ndarray:
        """Digital samples (2, n) float32 in [-1, 1] for eardrum pressure (2, n) in Pa."""
        p = np.asarray(pressure, dtype=float)
        if p.ndim != 2 or p.shape[0] != 2:
            raise ConfigError(f"microphone input must have shape (2, n), got {p.shape}")
        # One reduction instead of an elementwise test: any NaN or inf makes the sum
        # non-finite (a finite sum can only overflow for pressures beyond 1e300 Pa).
        if not np.isfinite(p.sum()) and not np.all(np.isfinite(p)):
            raise ConfigError("microphone input contains NaN or inf pressure")
        x = self.rng.standard_normal(p.shape)
        x *= self.noise_rms
        x += p
        if _LINEAR_FILTER is not None:
            out, self.zi = _LINEAR_FILTER(self.b, self.a, x, -1, self.zi)
        else:
            out, self.zi = signal.lfilter(self.b, self.a, x, axis=-1, zi=self.zi)
        # Quantize on the integer grid of the ADC: clip to its codes, round, scale back
        # (a power of two, exact in float32).
        out *= self._to_codes
        np.minimum(out, self.levels - 1, out=out)
        np.maximum(out, -self.levels, out=out)
        np.rint(out, out=out)
        q = out.astype(np.float32)
        q *= self._lsb
        return q
