"""Binaural sound-event examples for MelCNN: training data and held-out evaluation data.

One example is what one ear-frame's detector sees: the two normalised log-mel patches
(left, right; 25 frames = 0.4 s x 128 mel bands, :func:`~acoustic_sim.auditory.features.
log_mel_patches`) of a window of a short binaural *scene*, with the classes audible in that
window as labels. A scene (``scene_seconds`` long) is made like this:

1. **Room and positions.** A room is drawn from ``rooms`` (default ``anechoic``,
   ``car_cabin``, ``lab``, ``conference``). Sources go through binaural room impulse
   responses (BRIRs) from a :class:`BRIRBank`: per room, BRIRs precomputed with
   :meth:`BinauralRenderer.impulse_response` (KEMAR, image sources plus diffuse tail) for
   random source directions (azimuth uniform, elevation -30..60 deg) and distances
   (0.5-3 m, kept 0.1 m inside the walls). Convolving with a bank is exactly what the
   streaming renderer does for a static head and source, at a fraction of its cost.
2. **Sounds.** 0-3 distinct classes (``class_count_probs`` = 5/30/40/25 %) each play a
   1.5-3 s crop of an instance of :func:`acoustic_sim.acoustics.sounds.generate` (its
   own pitch, rhythm and pauses; a :class:`SoundPool` recycles each instance for about
   ``pool_reuse`` = 4 scenes with other crops: about 6 instead of 8.5 ms per window),
   starting anywhere from 1 s before the scene to 0.8 s before its end, so
   windows see onsets, steady parts, pauses, offsets and reverberant tails.
3. **Levels.** A diffuse background noise (:func:`diffuse_noise`: spectral slope
   -6..0 dB/octave, coherent between the ears below ~700 Hz) at ``background_db_spl``
   (30-70 dB SPL at the ears) and each class at an SNR of ``snr_db`` (0-30 dB): the
   instance's level (unit RMS over the whole instance) times the BRIR's energy gain, over
   the background power. The paper's room experiment (73-76 dB SPL at 1.5 m over a 58 dB
   background) sits in the middle of that range. Levels are set on the instance, not on
   the part that falls in the scene, so a crop that is mostly a pause stays quiet.
4. **Ears.** The sum goes through the ear unit's :class:`~acoustic_sim.acoustics.
   microphone.Microphone` (self-noise, high-pass, 24-bit ADC) and the front end
   (:func:`~acoustic_sim.auditory.frontend.analyze`).

Windows end every ``window_hop_frames`` frames from frame ``first_window_frame`` on.

Labels: audibility by energy, per ear
-------------------------------------
Generated sounds have onsets, silent gaps and decaying tails, so "class c was playing" is a
poor label for a 0.4 s window. Each class's ear signal is also analysed *alone*, and so is
the background, giving mel-band powers ``P_c(t, m)`` and ``P_noise(t, m)`` per frame t and
ear. The masker of class c is everything else, ``Q_c = mean_t P_noise + sum_{c' != c}
P_c'`` (the stationary background masks with its mean power per band: its frame-to-frame
dips are not holes a sound can be heard through). Class c is *audible* in a frame when it
stands ``audible_snr_db`` = 6 dB above its masker in at least ``audible_min_bands`` = 5
mel bands: clearly out of the noise, whose log power in a narrow band fluctuates by about
5 dB from frame to frame (a 0 dB, 3-band rule labelled sounds that nobody, and no network,
could see in the patch). With ``A`` the number of audible frames among the window's 25,
the target is the ramp

    y = clip((A - label_frames[0]) / (label_frames[1] - label_frames[0]), 0, 1)

with ``label_frames = (2, 6)``: 0 for at most two audible frames (a sound that only starts
in the newest frames, a last echo), 1 from 6 frames on (about 130 ms: frames are 46 ms
long and 16 ms apart), soft in between. The hard label, used for evaluation, is
``y >= 0.5``, i.e. ``A >= 4``. The binaural label is the maximum over the ears: a class is
present if either ear hears it.

Characteristic spectra
----------------------
For MelCNN's characteristic bins, every frame in which a class is audible at an ear adds
that class's power spectrum at that ear (1025 bins, the class's own signal), normalised to
unit sum so that loud and quiet frames count alike, into ``spectrum_sum[c]``.

Everything is drawn from the ``numpy.random.Generator`` passed in: the same seed gives the
same arrays, bit for bit (on one machine; ``human_voice`` uses ``espeak-ng`` when
installed).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import signal as sp_signal

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.microphone import FULL_SCALE_PA, Microphone
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory.features import MEL_FRAMES, N_MELS, mel_power, normalize_log_mel
from acoustic_sim.auditory.frontend import N_BINS, analyze
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, db_spl_to_pa, sph_to_vec

CLASSES: tuple[str, ...] = sounds.SOUND_CLASSES
"""The six classes, in the order of every label array."""

ROOMS: tuple[str, ...] = ("anechoic", "car_cabin", "lab", "conference")
"""Rooms the examples are rendered in by default."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class SoundDataConfig:
    """How scenes are drawn (see the module docstring).

    Parameters
    ----------
    scene_seconds : float
        Length of one scene in s (0.5-30); each gives several windows.
    first_window_frame : int
        Frame number (1-based) at which the first window ends, >= 25; earlier frames
        include the silence before the scene.
    window_hop_frames : int
        Frames between the ends of consecutive windows of a scene (>= 1).
    class_count_probs : tuple of float
        Probability of 0, 1, 2, ... distinct classes in a scene (sums to 1; at most 6).
    sound_seconds : tuple of float
        Range (s) of the length of each class's instance.
    start_seconds : tuple of float
        Range (s, relative to the scene start) of each instance's start.
    snr_db : tuple of float
        Range (dB) of each class's power at the ears over the background's.
    background_db_spl : tuple of float
        Range (dB SPL at the ears) of the background noise.
    noise_slope_db_per_octave : tuple of float
        Range of the background's spectral slope (power, dB per octave; -3 pink, -6 brown).
    rooms : tuple of str
        Room presets drawn uniformly.
    audible_snr_db : float
        Local SNR (dB) a mel band needs for the class to count as audible in it.
    audible_min_bands : int
        Mel bands that must pass ``audible_snr_db`` for an audible frame (1-128).
    label_frames : tuple of int
        ``(a0, a1)``: the target ramps from 0 at ``a0`` audible frames to 1 at ``a1``.
    pool_size : int
        Sound instances kept per class by :func:`generate_examples` (:class:`SoundPool`).
    pool_reuse : int
        Mean number of scenes an instance serves (1: every sound is fresh).
    """

    scene_seconds: float = 3.0
    first_window_frame: int = 30
    window_hop_frames: int = 12
    class_count_probs: tuple[float, ...] = (0.05, 0.3, 0.4, 0.25)
    sound_seconds: tuple[float, float] = (1.5, 3.0)
    start_seconds: tuple[float, float] = (-1.0, 2.2)
    snr_db: tuple[float, float] = (0.0, 30.0)
    background_db_spl: tuple[float, float] = (30.0, 70.0)
    noise_slope_db_per_octave: tuple[float, float] = (-6.0, 0.0)
    rooms: tuple[str, ...] = ROOMS
    audible_snr_db: float = 6.0
    audible_min_bands: int = 5
    label_frames: tuple[int, int] = (2, 6)
    pool_size: int = 40
    pool_reuse: int = 4

    def __post_init__(self) -> None:
        def rng_pair(name, lo, hi):
            v = getattr(self, name)
            if len(v) != 2 or not all(math.isfinite(x) for x in v) or not lo <= v[0] <= v[1] <= hi:
                raise ConfigError(f"SoundDataConfig.{name} must be (low, high) with {lo} <= low <= high <= {hi}, got {v}")

        if not 0.5 <= self.scene_seconds <= 30:
            raise ConfigError(f"SoundDataConfig.scene_seconds must be 0.5-30 s, got {self.scene_seconds}")
        n_frames = int(self.scene_seconds * 62.5)
        if not MEL_FRAMES <= self.first_window_frame <= n_frames:
            raise ConfigError(f"SoundDataConfig.first_window_frame must be {MEL_FRAMES}..{n_frames} "
                              f"(frames in a scene), got {self.first_window_frame}")
        if self.window_hop_frames < 1:
            raise ConfigError(f"SoundDataConfig.window_hop_frames must be >= 1, got {self.window_hop_frames}")
        p = np.asarray(self.class_count_probs, float)
        if p.size < 1 or p.size > len(CLASSES) + 1 or np.any(p < 0) or not np.isclose(p.sum(), 1.0):
            raise ConfigError(f"SoundDataConfig.class_count_probs must be 1-{len(CLASSES) + 1} "
                              f"probabilities summing to 1, got {self.class_count_probs}")
        rng_pair("sound_seconds", 0.05, 60.0)
        rng_pair("start_seconds", -60.0, self.scene_seconds)
        rng_pair("snr_db", -40.0, 60.0)
        rng_pair("background_db_spl", 0.0, 100.0)
        rng_pair("noise_slope_db_per_octave", -12.0, 6.0)
        if not self.rooms or any(r not in ("anechoic", "car_cabin", "lab", "conference") for r in self.rooms):
            raise ConfigError(f"SoundDataConfig.rooms must be presets among {ROOMS}, got {self.rooms}")
        if not 1 <= self.audible_min_bands <= N_MELS:
            raise ConfigError(f"SoundDataConfig.audible_min_bands must be 1..{N_MELS}, got {self.audible_min_bands}")
        if self.pool_size < 1 or self.pool_reuse < 1:
            raise ConfigError(f"SoundDataConfig.pool_size and pool_reuse must be >= 1, got {self.pool_size}, {self.pool_reuse}")
        a0, a1 = self.label_frames
        if not 0 <= a0 < a1 <= MEL_FRAMES:
            raise ConfigError(f"SoundDataConfig.label_frames must be (a0, a1) with 0 <= a0 < a1 <= {MEL_FRAMES}, "
                              f"got {self.label_frames}")

    def windows_per_scene(self) -> int:
        """Number of windows one scene yields."""
        n_frames = _frames_in(self.scene_seconds)
        return (n_frames - self.first_window_frame) // self.window_hop_frames + 1


@dataclasses.dataclass(frozen=True)
class SoundExamples:
    """A set of labelled binaural windows.

    Attributes
    ----------
    patches : numpy.ndarray
        (N, 2, 25, 128): normalised log-mel patches (left, right), values in [-1, 0];
        float32 unless another dtype was asked for.
    targets : numpy.ndarray
        float32 (N, 2, 6): soft per-ear targets in [0, 1] (the ramp of the module docstring).
    labels : numpy.ndarray
        bool (N, 6): binaural hard labels, ``max over ears of targets >= 0.5``.
    volumes : numpy.ndarray
        float64 (N, 2): ear volumes V_l, V_r (mean over the window's frames of
        :func:`~acoustic_sim.auditory.features.ear_volume`, full-scale units squared).
    room : numpy.ndarray
        int8 (N,): index into the config's ``rooms`` of each window's room.
    spectrum_sum : numpy.ndarray
        float64 (6, 1025): per class, the sum of its unit-sum power spectra over the frames
        (and ears) where it was audible.
    spectrum_frames : numpy.ndarray
        int64 (6,): number of those frames per class.
    """

    patches: np.ndarray
    targets: np.ndarray
    labels: np.ndarray
    volumes: np.ndarray
    room: np.ndarray
    spectrum_sum: np.ndarray
    spectrum_frames: np.ndarray

    def __len__(self) -> int:
        return int(self.labels.shape[0])


def _frames_in(seconds: float) -> int:
    n = round(seconds * SAMPLE_RATE)
    return int(np.floor(n * 62.5 / SAMPLE_RATE))


# --------------------------------------------------------------------------- BRIRs


class BRIRBank:
    """Binaural room impulse responses for random source positions, per room.

    Parameters
    ----------
    brirs : dict of str to list of numpy.ndarray
        Per room name, BRIRs of shape (2, L) (left, right): eardrum pressure (Pa) per unit
        pressure at 1 m from the source.
    """

    def __init__(self, brirs: dict[str, list[np.ndarray]]) -> None:
        if not brirs or any(len(v) == 0 for v in brirs.values()):
            raise ConfigError("a BRIR bank needs at least one BRIR per room")
        self.brirs = brirs

    @classmethod
    def build(cls, rng: np.random.Generator, *, rooms=ROOMS, per_room: int = 8, hrtf=None,
              distance_m=(0.5, 3.0), elevation_deg=(-30.0, 60.0), progress: bool = False) -> BRIRBank:
        """Render BRIRs for ``per_room`` random positions in each room.

        Parameters
        ----------
        rng : numpy.random.Generator
            Draws the positions and the rooms' diffuse tails.
        rooms : sequence of str
            Room presets.
        per_room : int
            BRIRs per room, >= 1 (each takes about 0.3-0.6 s to render).
        hrtf : acoustic_sim.acoustics.hrtf.HRTF, optional
            The ears; default the bundled KEMAR.
        distance_m : tuple of float
            Range of source distances from the head centre (m); positions are pulled in to
            stay 0.1 m inside the walls (and at least 0.3 m from the head).
        elevation_deg : tuple of float
            Range of source elevations (deg, head frame); azimuth is uniform.
        progress : bool
            Show a progress bar.
        """
        from acoustic_sim.acoustics.hrtf import HRTF

        if per_room < 1:
            raise ConfigError(f"per_room must be >= 1, got {per_room}")
        hrtf = HRTF.load("kemar") if hrtf is None else hrtf
        jobs = [(r, i) for r in rooms for i in range(per_room)]
        bar = _progress(len(jobs), "BRIR bank", progress)
        out: dict[str, list[np.ndarray]] = {}
        for name in rooms:
            room = room_preset(name)
            renderer = BinauralRenderer(hrtf, room, rng=rng)
            head = np.asarray(room.listener, float)
            out[name] = []
            for _ in range(per_room):
                pos = _random_position(room, head, rng, distance_m, elevation_deg)
                out[name].append(renderer.impulse_response(pos))
                bar.update(1)
        bar.close()
        return cls(out)


def _random_position(room, head, rng, distance_m, elevation_deg) -> np.ndarray:
    for _ in range(1000):
        v = sph_to_vec(rng.uniform(-180.0, 180.0), rng.uniform(*elevation_deg))
        r = rng.uniform(*distance_m)
        if room.anechoic:
            return head + r * v
        # Largest distance along v that keeps 0.1 m from every wall.
        dims = np.asarray(room.dimensions, float)
        with np.errstate(divide="ignore"):
            t_hi = np.where(v > 0, (dims - 0.1 - head) / v, np.where(v < 0, (0.1 - head) / v, np.inf))
        reach = float(np.min(t_hi))
        if reach >= 0.3:
            return head + min(r, reach) * v
    raise ConfigError(f"room {room.name!r}: no source position 0.3 m from the head fits inside")


# --------------------------------------------------------------------------- signals


def diffuse_noise(n: int, rng: np.random.Generator, *, slope_db_per_octave: float = -3.0,
                  crossover_hz: float = 700.0, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Two-ear diffuse background noise with a power-law spectrum, unit mean power.

    Parameters
    ----------
    n : int
        Samples per ear (>= 2).
    rng : numpy.random.Generator
        The only source of randomness.
    slope_db_per_octave : float
        Power spectral density slope in dB per octave (0 white, -3 pink, -6 brown),
        applied from 50 Hz up (flat below, nothing below 20 Hz).
    crossover_hz : float
        Interaural coherence is ``1 / (1 + (f / crossover_hz)**2)``: a diffuse field is
        coherent where the head is small against the wavelength, incoherent above.
    sample_rate : int
        Hz.

    Returns
    -------
    numpy.ndarray
        float64 (2, n), mean square over both ears exactly 1 (dimensionless; scale to Pa).
    """
    if n < 2:
        raise ConfigError(f"noise length must be >= 2 samples, got {n}")
    f = np.fft.rfftfreq(n, 1.0 / sample_rate)
    shape = (np.maximum(f, 50.0) / 1000.0) ** (slope_db_per_octave / (20.0 * np.log10(2.0)))
    shape[f < 20.0] = 0.0
    gamma = 1.0 / (1.0 + (f / crossover_hz) ** 2)
    z = rng.standard_normal((2, 2, f.size))
    z = z[:, 0] + 1j * z[:, 1]
    spec = np.stack([z[0], gamma * z[0] + np.sqrt(1.0 - gamma**2) * z[1]]) * shape
    x = np.fft.irfft(spec, n=n, axis=-1)
    return x / np.sqrt(np.mean(x**2))


class SoundPool:
    """Sound instances recycled across scenes, to spend less time synthesising.

    Per class, up to ``size`` instances of ``seconds`` s from
    :func:`acoustic_sim.acoustics.sounds.generate` (unit RMS over the instance). Each
    request returns a random crop of a random instance; a fresh instance is made (into a
    free slot, else replacing a random one) while the pool fills and then with probability
    ``1 / reuse``, so on average an instance serves ``reuse`` scenes, each time with another
    crop, room position, level and background.

    Parameters
    ----------
    seconds : float
        Length of each instance (s); crops are at most this long.
    size : int
        Instances kept per class (>= 1).
    reuse : int
        Mean number of requests an instance serves (>= 1; 1 makes every request fresh).
    """

    FADE_S = 0.005
    """Fade (s) at a crop's cut ends, so a cut never clicks."""

    def __init__(self, *, seconds: float, size: int, reuse: int) -> None:
        if size < 1 or reuse < 1 or not seconds > 0:
            raise ConfigError(f"SoundPool needs seconds > 0, size >= 1 and reuse >= 1, got {seconds}, {size}, {reuse}")
        self.seconds, self.size, self.reuse = float(seconds), int(size), int(reuse)
        self.instances: dict[int, list[np.ndarray]] = {c: [] for c in range(len(CLASSES))}

    def crop(self, c: int, seconds: float, rng: np.random.Generator) -> np.ndarray:
        """A ``seconds``-long (at most the instance length) crop of an instance of class index ``c``."""
        pool = self.instances[c]
        if len(pool) < self.size or rng.random() < 1.0 / self.reuse:
            x = sounds.generate(CLASSES[c], rng, seconds=self.seconds).astype(np.float32)
            if len(pool) < self.size:
                pool.append(x)
            else:
                pool[int(rng.integers(self.size))] = x
        else:
            x = pool[int(rng.integers(len(pool)))]
        n = min(round(seconds * SAMPLE_RATE), x.size)
        offset = int(rng.integers(0, x.size - n + 1))
        out = x[offset:offset + n].astype(np.float64)
        f = min(round(self.FADE_S * SAMPLE_RATE), n // 2)
        ramp = np.sin(0.5 * np.pi * (np.arange(f) + 0.5) / f) ** 2
        if offset > 0:
            out[:f] *= ramp
        if offset + n < x.size:
            out[n - f:] *= ramp[::-1]
        return out


@dataclasses.dataclass
class _Scene:
    digital: np.ndarray  # (2, n) float32 microphone output
    classes: list[int]  # classes present in the scene
    ears: list[np.ndarray]  # per present class: (2, n) eardrum pressure (Pa)
    noise: np.ndarray  # (2, n) background pressure (Pa)
    room: int


def _scene(cfg: SoundDataConfig, bank: BRIRBank, rng: np.random.Generator, pool: SoundPool) -> _Scene:
    sr = SAMPLE_RATE
    n = round(cfg.scene_seconds * sr)
    room_i = int(rng.integers(len(cfg.rooms)))
    brirs = bank.brirs[cfg.rooms[room_i]]
    k = int(rng.choice(len(cfg.class_count_probs), p=np.asarray(cfg.class_count_probs, float)))
    chosen = sorted(int(c) for c in rng.choice(len(CLASSES), size=k, replace=False))
    background_pa = db_spl_to_pa(rng.uniform(*cfg.background_db_spl))
    classes, ears = [], []
    for c in chosen:
        brir = brirs[int(rng.integers(len(brirs)))]
        start = round(rng.uniform(*cfg.start_seconds) * sr)
        snr = rng.uniform(*cfg.snr_db)
        x = pool.crop(c, rng.uniform(*cfg.sound_seconds), rng)
        lo, hi = max(start, 0), min(start + x.size, n)
        if hi <= lo or not np.any(x[lo - start:hi - start]):
            continue  # nothing of the instance plays within the scene
        dry = np.zeros(n)
        dry[lo:hi] = x[lo - start:hi - start]
        wet = sp_signal.oaconvolve(dry[None, :], brir, axes=1)[:, :n]
        # The level is set on the instance as a whole (unit RMS) through the BRIR's energy
        # gain, not on the part that falls in the scene: a crop that is mostly a pause must
        # stay quiet, not be blown up to the target level.
        gain = background_pa * 10.0 ** (snr / 20.0) / math.sqrt(float(np.mean(np.sum(brir**2, axis=1))))
        classes.append(c)
        ears.append(wet * gain)
    noise = diffuse_noise(n, rng, slope_db_per_octave=rng.uniform(*cfg.noise_slope_db_per_octave)) * background_pa
    pressure = noise + (np.sum(ears, axis=0) if ears else 0.0)
    digital = Microphone(rng=rng)(pressure)
    return _Scene(digital, classes, ears, noise, room_i)


def _power_spectra(pressure: np.ndarray) -> np.ndarray:
    """Power spectra (K, 2, N_BINS) float32 of eardrum pressure (Pa) in full-scale units."""
    s = analyze(pressure / FULL_SCALE_PA).spectra
    return s.real**2 + s.imag**2


def audibility(mel_classes: np.ndarray, mel_noise: np.ndarray, cfg: SoundDataConfig) -> np.ndarray:
    """Which classes are audible in which frames, at each ear.

    Parameters
    ----------
    mel_classes : numpy.ndarray
        (C, K, 2, M) mel-band power of each class alone at the ears (full-scale units).
    mel_noise : numpy.ndarray
        (K, 2, M) mel-band power of the background alone.
    cfg : SoundDataConfig

    Returns
    -------
    numpy.ndarray
        bool (C, K, 2): the class exceeds its masker by ``audible_snr_db`` in at least
        ``audible_min_bands`` bands. The background, being stationary, masks with its mean
        power per band over the scene (its frame-to-frame dips are not holes a sound can
        be heard through: a band of one FFT bin fluctuates like an exponential variable);
        the other classes mask with their power in the same frame.
    """
    noise = mel_noise.mean(axis=0, keepdims=True)[None]  # (1, 1, 2, M)
    others = mel_classes.sum(axis=0, keepdims=True) - mel_classes + noise
    loud = (mel_classes > others * 10.0 ** (cfg.audible_snr_db / 10.0)) & (mel_classes > 0)
    return loud.sum(axis=-1) >= cfg.audible_min_bands


def scene_examples(cfg: SoundDataConfig, bank: BRIRBank, rng: np.random.Generator, *,
                   pool: SoundPool | None = None, dtype=np.float32) -> SoundExamples:
    """Draw one scene and return its windows (see the module docstring).

    Parameters
    ----------
    cfg : SoundDataConfig
    bank : BRIRBank
        Must hold every room of ``cfg.rooms``.
    rng : numpy.random.Generator
    pool : SoundPool, optional
        Where the sounds come from; default: fresh instances for this scene only.
    dtype : numpy dtype
        dtype of the patches (float32; float16 halves the memory of large training sets).

    Returns
    -------
    SoundExamples
        ``cfg.windows_per_scene()`` windows.
    """
    missing = [r for r in cfg.rooms if r not in bank.brirs]
    if missing:
        raise ConfigError(f"the BRIR bank has no BRIRs for rooms {missing}")
    if pool is None:
        pool = SoundPool(seconds=cfg.sound_seconds[1], size=1, reuse=1)
    sc = _scene(cfg, bank, rng, pool)
    spectra = analyze(sc.digital).spectra  # (K, 2, F)
    mel_total = mel_power(spectra)  # (K, 2, M)
    volume = np.mean(spectra.real.astype(np.float64) ** 2 + spectra.imag.astype(np.float64) ** 2, axis=-1)  # (K, 2)
    n_frames = spectra.shape[0]
    ends = np.arange(cfg.first_window_frame - 1, n_frames, cfg.window_hop_frames)  # 0-based last frame
    w = ends.size
    idx = ends[:, None] + np.arange(-MEL_FRAMES + 1, 1)[None, :]  # (W, 25)

    patches = normalize_log_mel(mel_total[idx].transpose(0, 2, 1, 3)).astype(dtype)  # (W, 2, 25, M)
    volumes = volume[idx].mean(axis=1)  # (W, 2)

    n_cls = len(CLASSES)
    targets = np.zeros((w, 2, n_cls), np.float32)
    spectrum_sum = np.zeros((n_cls, N_BINS))
    spectrum_frames = np.zeros(n_cls, np.int64)
    if sc.classes:
        power = [_power_spectra(e) for e in sc.ears]  # each (K, 2, F)
        mel_cls = np.stack([mel_power(np.sqrt(p)) for p in power])  # (C, K, 2, M)
        mel_noise = mel_power(np.sqrt(_power_spectra(sc.noise)))
        audible = audibility(mel_cls, mel_noise, cfg)  # (C, K, 2)
        count = audible[:, idx].sum(axis=2)  # (C, W, 2)
        a0, a1 = cfg.label_frames
        ramp = np.clip((count - a0) / (a1 - a0), 0.0, 1.0).astype(np.float32)
        for j, c in enumerate(sc.classes):
            targets[:, :, c] = ramp[j]
            frames = power[j][audible[j]]  # (n, F) spectra of audible (frame, ear) pairs
            totals = frames.sum(axis=-1, keepdims=True)
            ok = totals[:, 0] > 0
            spectrum_sum[c] += (frames[ok] / totals[ok]).sum(axis=0)
            spectrum_frames[c] += int(ok.sum())
    labels = targets.max(axis=1) >= 0.5
    return SoundExamples(patches, targets, labels, volumes, np.full(w, sc.room, np.int8), spectrum_sum, spectrum_frames)


def generate_examples(n_examples: int, rng: np.random.Generator, *, config: SoundDataConfig | None = None,
                      bank: BRIRBank | None = None, brirs_per_room: int = 8, dtype=np.float32,
                      progress: bool = False) -> SoundExamples:
    """Generate ``n_examples`` labelled windows from fresh random scenes.

    Parameters
    ----------
    n_examples : int
        Number of windows, >= 1 (the last scene's surplus windows are dropped).
    rng : numpy.random.Generator
        The only source of randomness: positions, sounds, levels, noise. Use independent
        streams for training and evaluation (e.g. ``SeedSequence(seed).spawn``).
    config : SoundDataConfig, optional
        Scene parameters (default ``SoundDataConfig()``).
    bank : BRIRBank, optional
        BRIRs to use; default: a new bank of ``brirs_per_room`` BRIRs per room, drawn from
        ``rng`` first (so held-out data also has unseen source positions).
    brirs_per_room : int
        Size of the default bank per room.
    dtype : numpy dtype
        dtype of the patches.
    progress : bool
        Show progress bars.

    Returns
    -------
    SoundExamples
    """
    if isinstance(n_examples, bool) or not isinstance(n_examples, (int, np.integer)) or n_examples < 1:
        raise ConfigError(f"n_examples must be a positive integer, got {n_examples!r}")
    if not isinstance(rng, np.random.Generator):
        raise ConfigError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    cfg = SoundDataConfig() if config is None else config
    if bank is None:
        bank = BRIRBank.build(rng, rooms=cfg.rooms, per_room=brirs_per_room, progress=progress)
    pool = SoundPool(seconds=cfg.sound_seconds[1], size=cfg.pool_size, reuse=cfg.pool_reuse)
    parts: list[SoundExamples] = []
    have = 0
    bar = _progress(int(n_examples), "sound examples", progress)
    while have < n_examples:
        ex = scene_examples(cfg, bank, rng, pool=pool, dtype=dtype)
        take = min(len(ex), n_examples - have)
        parts.append(ex)
        have += take
        bar.update(take)
    bar.close()
    return _concat(parts, int(n_examples))


def _concat(parts: list[SoundExamples], n: int) -> SoundExamples:
    return SoundExamples(
        patches=np.concatenate([p.patches for p in parts])[:n],
        targets=np.concatenate([p.targets for p in parts])[:n],
        labels=np.concatenate([p.labels for p in parts])[:n],
        volumes=np.concatenate([p.volumes for p in parts])[:n],
        room=np.concatenate([p.room for p in parts])[:n],
        spectrum_sum=np.sum([p.spectrum_sum for p in parts], axis=0),
        spectrum_frames=np.sum([p.spectrum_frames for p in parts], axis=0),
    )


def _progress(total: int, desc: str, enabled: bool):
    from acoustic_sim.progress import progress_bar

    return progress_bar(total=total, desc=desc, disable=not enabled, unit="ex" if "example" in desc else "it",
                dynamic_ncols=True, leave=False)
