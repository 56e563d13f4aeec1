"""Ego-noise: the robot's own motors heard at its ears (the paper's "driving noise").

Musashi's actuators (geared DC motors) whine and rattle while they move or push; the
ears sit on the same body, so the pipeline always hears them. The paper records that
noise in advance and ignores every spectral bin below 10 times the driving spectrum.
This module makes the noise from the robot's actual actuator state, once per control step,
and tells the pipeline its expected spectrum at the current level.

Level model
-----------
Each actuator ``i`` has an activity (dimensionless)::

    a_i = w_i * (|v_i| / speed_ref + |f_i| / effort_ref_i)

with ``v_i`` its actuator velocity (rad/s for hinges, m/s for slides), ``f_i`` its
actuator force (N m or N), ``effort_ref_i`` its force limit when the model sets one (else
:attr:`EgoNoiseConfig.effort_ref`) and ``w_i`` an amplitude weight per actuator group
(the wheelchair's drive motors are louder than the arm motors). Independent motors add in
power, so the RMS pressure at each ear is::

    p = p_1 * sqrt(sum_i a_i**2),   p_1 = 20 uPa * 10**(level_db / 20)

i.e. ``L = level_db + 10 log10(sum_i a_i**2)`` dB SPL, capped at ``max_level_db``: one
motor at ``speed_ref`` gives ``level_db``, doubling every speed gives +6 dB, and a robot
at rest with no effort is exactly silent.

Spectrum
--------
A fixed motor-whine shape: white noise band-limited to ``band_hz`` (4th-order
Butterworth band-pass: brush and bearing noise), with peaks of ``whine_gain_db`` at the
first ``whine_harmonics`` harmonics of ``whine_hz`` (gear mesh and PWM whine; RBJ peaking
filters of quality ``whine_q``). The shape is fixed and only the level follows the
activity, as with the paper's pre-recorded driving spectra: the thresholds then scale with
the level and nothing else. Both ears get the same level; the noise is partially
coherent between them (``coherence``), as from sources inside the body.

The level changes once per block; within a block the gain ramps linearly from the old to
the new value, so level changes do not click.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal

from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, db_spl_to_pa, pa_to_db_spl
from acoustic_sim.world import names


@dataclasses.dataclass(frozen=True, kw_only=True)
class EgoNoiseConfig:
    """Parameters of the motor ego-noise.

    Parameters
    ----------
    level_db : float
        dB SPL at each ear of one actuator at activity 1 (moving at ``speed_ref``, no
        load); 0-100. Default 42 dB: a small geared servo heard from 20-30 cm.
    speed_ref : float
        Actuator speed (rad/s, or m/s for slides) that counts as activity 1; > 0.
    effort_ref : float
        Force (N m, or N) that counts as activity 1 for actuators whose model sets no force
        limit; > 0. Actuators with a force limit use that limit.
    max_level_db : float
        Upper bound of the level (dB SPL), 0-130.
    group_weights : tuple of (str, float)
        Actuator name prefix and amplitude weight ``w_i`` (>= 0); actuators whose names
        start with none of the prefixes make no noise. Default: the robot's motors 1, the
        wheelchair's drive motors 2 (+6 dB).
    band_hz : tuple of 2 float
        Band-pass corners (Hz) of the broadband part, 20 <= lo < hi < 0.45 * sample rate.
    whine_hz : float
        Fundamental (Hz) of the whine peaks; > 20.
    whine_harmonics : int
        Number of whine peaks (harmonics 1..n below 0.45 * sample rate), 0-10.
    whine_gain_db : float
        Height of each whine peak above the broadband shape (dB), 0-40.
    whine_q : float
        Quality factor of the whine peaks, 1-100.
    coherence : float
        Interaural coherence of the noise, 0-1.
    """

    level_db: float = 42.0
    speed_ref: float = 1.0
    effort_ref: float = 10.0
    max_level_db: float = 95.0
    group_weights: tuple[tuple[str, float], ...] = ((names.ROBOT, 1.0), (names.WHEELCHAIR, 2.0))
    band_hz: tuple[float, float] = (150.0, 6000.0)
    whine_hz: float = 1150.0
    whine_harmonics: int = 3
    whine_gain_db: float = 15.0
    whine_q: float = 8.0
    coherence: float = 0.5

    def __post_init__(self) -> None:
        checks = [
            ("level_db", 0.0 <= self.level_db <= 100.0, "0..100 dB SPL"),
            ("speed_ref", self.speed_ref > 0, "> 0"),
            ("effort_ref", self.effort_ref > 0, "> 0"),
            ("max_level_db", 0.0 <= self.max_level_db <= 130.0, "0..130 dB SPL"),
            ("whine_hz", self.whine_hz > 20.0, "> 20 Hz"),
            ("whine_harmonics", isinstance(self.whine_harmonics, int) and 0 <= self.whine_harmonics <= 10, "an integer 0..10"),
            ("whine_gain_db", 0.0 <= self.whine_gain_db <= 40.0, "0..40 dB"),
            ("whine_q", 1.0 <= self.whine_q <= 100.0, "1..100"),
            ("coherence", 0.0 <= self.coherence <= 1.0, "0..1"),
        ]
        for field, ok, expected in checks:
            value = getattr(self, field)
            if not ok or (isinstance(value, float) and not np.isfinite(value)):
                raise ConfigError(f"EgoNoiseConfig.{field} must be {expected}, got {value!r}")
        lo, hi = self.band_hz
        if not 20.0 <= lo < hi:
            raise ConfigError(f"EgoNoiseConfig.band_hz must be (lo, hi) with 20 <= lo < hi Hz, got {self.band_hz}")
        for prefix, weight in self.group_weights:
            if not isinstance(prefix, str) or not np.isfinite(weight) or weight < 0:
                raise ConfigError(f"EgoNoiseConfig.group_weights: each entry must be (prefix, weight >= 0), got {(prefix, weight)}")


class MotorEgoNoise:
    """Motor noise at both ears; satisfies the renderer's ``EgoNoise`` protocol.

    Parameters
    ----------
    weights : array_like, shape (m,)
        Amplitude weight ``w_i`` of each noisy actuator (>= 0).
    effort_refs : array_like, shape (m,)
        Force (N m or N) that counts as activity 1 for each actuator (> 0).
    config : EgoNoiseConfig
    sample_rate : int
        Hz.

    Notes
    -----
    Build it from a world with :meth:`from_view`; then call :meth:`update` (or
    :meth:`set_activity`) once per control step, before the renderer renders the block.
    """

    def __init__(self, weights, effort_refs, config: EgoNoiseConfig | None = None, *, sample_rate: int = SAMPLE_RATE) -> None:
        self.config = config or EgoNoiseConfig()
        self.weights = np.asarray(weights, dtype=float).reshape(-1)
        self.effort_refs = np.asarray(effort_refs, dtype=float).reshape(-1)
        if self.weights.shape != self.effort_refs.shape:
            raise ConfigError(f"ego noise: {self.weights.size} weights but {self.effort_refs.size} effort references")
        if np.any(~np.isfinite(self.weights)) or np.any(self.weights < 0):
            raise ConfigError("ego noise: weights must be finite and >= 0")
        if np.any(~np.isfinite(self.effort_refs)) or np.any(self.effort_refs <= 0):
            raise ConfigError("ego noise: effort references must be finite and > 0 (N m or N)")
        if not 8000 <= sample_rate <= 384000:
            raise ConfigError(f"ego noise: sample_rate must be 8000..384000 Hz, got {sample_rate}")
        self.sample_rate = int(sample_rate)
        self.sos = motor_whine_sos(self.config, self.sample_rate)
        # Unit RMS output for unit-variance white input (the filter's energy, IIR decays fast).
        impulse = np.zeros(1 << 15)
        impulse[0] = 1.0
        self._h = signal.sosfilt(self.sos, impulse)
        self._norm = 1.0 / np.sqrt(np.sum(self._h**2))
        self._zi = np.zeros((self.sos.shape[0], 3, 2))  # sections x (common, left, right) x state
        self._gain = 0.0  # Pa RMS applied at the end of the last block
        self._target = 0.0  # Pa RMS for the next block
        self._spectrum_cache: dict = {}
        self._max_pa = float(db_spl_to_pa(self.config.max_level_db))
        self._p1 = float(db_spl_to_pa(self.config.level_db))
        self._speed_w = self.weights / self.config.speed_ref  # a_i = these times |v_i| and |f_i|
        self._effort_w = self.weights / self.effort_refs
        self.activity = 0.0
        """Total activity ``sqrt(sum_i a_i**2)`` (dimensionless) of the last update."""
        self.actuator_indices: np.ndarray | None = None
        """Indices (into the model's actuators) this noise listens to, when built by :meth:`from_view`."""

    @classmethod
    def from_view(cls, view, config: EgoNoiseConfig | None = None, *, sample_rate: int = SAMPLE_RATE) -> MotorEgoNoise:
        """Ego-noise for the actuators of a world (see :class:`~acoustic_sim.world.view.WorldView`).

        Actuators are selected and weighted by ``config.group_weights`` (name prefixes).
        """
        config = config or EgoNoiseConfig()
        info = view.actuator_info()
        weights = np.zeros(len(info.names))
        for i, name in enumerate(info.names):
            for prefix, w in config.group_weights:
                if name.startswith(prefix):
                    weights[i] = w
                    break
        refs = np.where(info.force_limit > 0, info.force_limit, config.effort_ref)
        noisy = np.flatnonzero(weights > 0)
        obj = cls(weights[noisy], refs[noisy], config, sample_rate=sample_rate)
        obj.actuator_indices = noisy
        return obj

    # -- level --------------------------------------------------------------------------------
    def set_activity(self, speeds, efforts) -> float:
        """Set the level for the next block from actuator speeds and forces.

        Parameters
        ----------
        speeds : array_like, shape (m,)
            Actuator velocities (rad/s or m/s).
        efforts : array_like, shape (m,)
            Actuator forces (N m or N).

        Returns
        -------
        float
            The new RMS pressure (Pa) at each ear; 0 at rest.
        """
        v = np.asarray(speeds, dtype=float)
        f = np.asarray(efforts, dtype=float)
        if v.shape != self.weights.shape or f.shape != self.weights.shape:
            raise ConfigError(f"ego noise: expected {self.weights.size} speeds and efforts, got shapes {v.shape} and {f.shape}")
        a = self._speed_w * np.abs(v) + self._effort_w * np.abs(f)
        activity = math.sqrt(float(a @ a))
        if not math.isfinite(activity):
            raise ConfigError("ego noise: actuator speeds or forces are not finite (did the simulation diverge?)")
        self.activity = activity
        self._target = min(self._p1 * activity, self._max_pa)
        return self._target

    def update(self, view) -> float:
        """Read the actuators from a world view and set the next block's level; returns the
        RMS pressure (Pa) at each ear."""
        if self.actuator_indices is None:
            raise ConfigError("ego noise: update(view) needs an object built with MotorEgoNoise.from_view")
        speeds, forces = view.actuator_state()
        return self.set_activity(speeds.take(self.actuator_indices), forces.take(self.actuator_indices))

    @property
    def level_db(self) -> float:
        """Level (dB SPL at each ear) of the next block; -inf when silent."""
        return float(pa_to_db_spl(self._target))

    @property
    def pressure_rms(self) -> float:
        """RMS pressure (Pa) at each ear of the next block."""
        return self._target

    # -- EgoNoise protocol --------------------------------------------------------------------
    def __call__(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """The next ``n`` samples (2, n) of pressure (Pa) at the left and right ear."""
        if not isinstance(n, (int, np.integer)) or n <= 0:
            raise ConfigError(f"ego noise: block length must be a positive integer, got {n!r}")
        w = rng.standard_normal((3, n))
        # Filter even when silent so that the filter state (and the rng stream) does not
        # depend on the level history.
        y, self._zi = signal.sosfilt(self.sos, w, axis=-1, zi=self._zi)
        c = np.sqrt(self.config.coherence)
        s = np.sqrt(1.0 - self.config.coherence)
        ears = (c * y[0] + s * y[1:]) * self._norm
        gain = self._gain + (self._target - self._gain) * (np.arange(1, n + 1) / n)
        self._gain = self._target
        return ears * gain

    # -- spectrum -----------------------------------------------------------------------------
    def expected_power_spectrum(self, nfft: int = 2048, window="hamming", *, level_db: float | None = None) -> np.ndarray:
        """Expected power ``E|X_k|^2`` (Pa^2) per rFFT bin of one ear's windowed noise.

        ``X = rfft(window * x)`` for ``nfft`` consecutive samples ``x`` at a constant
        level: the quantity the front end computes every frame. Exact for the stationary
        process (the window's leakage of the whine peaks included), computed from the
        filter's autocorrelation and the window's.

        Parameters
        ----------
        nfft : int
            Frame length (samples), 16-65536.
        window : str or array_like, shape (nfft,)
            A ``scipy.signal.get_window`` name (periodic, as for spectral analysis) or the
            front end's own window samples.
        level_db : float, optional
            Level (dB SPL); default the level of the next block.

        Returns
        -------
        numpy.ndarray, shape (nfft // 2 + 1,)
            Pa^2 per bin; zeros at rest. ``sqrt`` of it is the RMS magnitude ``|X_k|`` of
            the noise (a Gaussian bin's mean magnitude is ``sqrt(pi / 4)`` of that). The
            paper's threshold is 10 times the driving spectrum per bin.
        """
        if level_db is None:
            p = self._target
        else:
            if not np.isfinite(level_db) and level_db != -np.inf:
                raise ConfigError(f"ego noise: level_db must be a number of dB SPL, got {level_db}")
            p = float(db_spl_to_pa(level_db))
        return self.unit_power_spectrum(nfft, window) * p**2

    def unit_power_spectrum(self, nfft: int = 2048, window="hamming") -> np.ndarray:
        """:meth:`expected_power_spectrum` at 1 Pa RMS (Pa^2 per bin per Pa^2): the shape
        that the level scales, for callers that follow the level block by block."""
        if not isinstance(nfft, (int, np.integer)) or not 16 <= nfft <= 65536:
            raise ConfigError(f"ego noise: nfft must be an integer 16..65536, got {nfft!r}")
        if isinstance(window, str):
            try:
                win = signal.get_window(window, nfft)
            except ValueError as err:
                raise ConfigError(f"ego noise: unknown window {window!r} ({err})") from None
        else:
            win = np.asarray(window, dtype=float)
            if win.shape != (nfft,) or not np.all(np.isfinite(win)):
                raise ConfigError(f"ego noise: window must be {nfft} finite samples, got shape {win.shape}")
        return self._unit_spectrum(nfft, win)

    def _unit_spectrum(self, nfft: int, win: np.ndarray) -> np.ndarray:
        key = (nfft, win.tobytes())
        cache = self._spectrum_cache
        if key not in cache:
            # E|X_k|^2 = sum_l R(l) r_w(l) exp(-2j pi k l / N): R the noise autocorrelation
            # (unit variance), r_w the window's; both symmetric, so fold the lags mod N.
            m = 1 << int(np.ceil(np.log2(self._h.size + nfft)) + 1)
            hh = np.fft.rfft(self._h * self._norm, n=m)
            r = np.fft.irfft(np.abs(hh) ** 2, n=m)
            wf = np.fft.rfft(win, n=2 * nfft)
            rw = np.fft.irfft(np.abs(wf) ** 2, n=2 * nfft)
            lags = np.arange(-(nfft - 1), nfft)
            prod = r[lags % m] * rw[lags % (2 * nfft)]
            folded = np.zeros(nfft)
            np.add.at(folded, lags % nfft, prod)
            cache[key] = np.maximum(np.fft.rfft(folded).real, 0.0)
        return cache[key]


def motor_whine_sos(config: EgoNoiseConfig, sample_rate: int) -> np.ndarray:
    """Second-order sections of the motor-whine shaping filter (band-pass and peaks)."""
    lo, hi = config.band_hz
    if hi >= 0.45 * sample_rate:
        raise ConfigError(f"EgoNoiseConfig.band_hz upper corner {hi} Hz must be below 0.45 * {sample_rate} Hz")
    sections = [signal.butter(2, [lo, hi], "bandpass", fs=sample_rate, output="sos")]
    gain = 10.0 ** (config.whine_gain_db / 40.0)  # RBJ "A": amplitude sqrt of the peak gain
    for h in range(1, config.whine_harmonics + 1):
        f = h * config.whine_hz
        if f >= 0.45 * sample_rate:
            break
        w0 = 2.0 * np.pi * f / sample_rate
        alpha = np.sin(w0) / (2.0 * config.whine_q)
        b = np.array([1.0 + alpha * gain, -2.0 * np.cos(w0), 1.0 - alpha * gain])
        a = np.array([1.0 + alpha / gain, -2.0 * np.cos(w0), 1.0 - alpha / gain])
        sections.append(np.concatenate([b / a[0], a / a[0]])[None, :])
    return np.vstack(sections)

