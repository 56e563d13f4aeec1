"""SSDENet's bins and training recipes: which frequency bins get a network, and the profiles.

A bank of per-bin networks (:class:`~acoustic_sim.auditory.ssdenet.bank.SSDENetBank`)
localises a sound only through the bins that have a network, so the choice of bins is part
of a profile, beside the network size and the training recipe. :data:`PAPER` is the paper's
network size on 32 bins (:func:`harmonic_bins`; the reasons and measurements are in
docs/notes/ssdenet_recipes.md), :data:`FAST` a small bank for tests and the tasks'
regression tests, :data:`QUICK` a smaller one for the quick paper evaluation. All are
re-exported by :mod:`acoustic_sim.auditory.ssdenet`.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from acoustic_sim.auditory.frontend import N_BINS, N_FFT, bin_frequencies
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

N_FEATURES = 5
"""Inputs per bin: ILD and the Re/Im of both unit phasors."""



def erb_number(freq_hz) -> np.ndarray:
    """ERB-rate (Glasberg & Moore 1990) of frequencies in Hz: 21.4 log10(1 + 0.00437 f)."""
    return 21.4 * np.log10(1.0 + 0.00437 * np.asarray(freq_hz, dtype=float))


AUDIOMETRIC_HZ = (500.0, 750.0, 1000.0, 1500.0, 2000.0, 3000.0, 4000.0, 6000.0, 8000.0)
"""Pure-tone audiometry frequencies (ISO 8253-1) between 300 Hz and 12 kHz, in Hz."""


def erb_spaced_bins(n: int, fmin_hz: float = 300.0, fmax_hz: float = 12000.0, *, anchors_hz=(),
                    n_fft: int = N_FFT, sample_rate: int = SAMPLE_RATE) -> tuple[int, ...]:
    """``n`` rFFT bins equally spaced on the ERB-rate scale, optionally moved onto anchors.

    Parameters
    ----------
    n : int
        Number of bins, >= 1. With ``n = 1`` the bin nearest ``fmin_hz``.
    fmin_hz, fmax_hz : float
        Band edges in Hz (both included), 0 < fmin_hz < fmax_hz <= sample_rate / 2.
    anchors_hz : sequence of float
        Frequencies (Hz, inside the band) that must have a bin: each replaces the
        ERB-spaced frequency nearest to it on the ERB-rate scale (each anchor a different one).
    n_fft, sample_rate : int
        FFT size and sample rate in Hz (bin k is at k * sample_rate / n_fft Hz).

    Returns
    -------
    tuple of int
        Increasing, distinct bin indices.

    Raises
    ------
    ConfigError
        Bad arguments, anchors outside the band or competing for one bin, or more bins than
        the band holds.
    """
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ConfigError(f"number of bins must be an integer >= 1, got {n!r}")
    if not (0 < fmin_hz < fmax_hz <= sample_rate / 2):
        raise ConfigError(f"need 0 < fmin_hz < fmax_hz <= {sample_rate / 2} Hz, got {fmin_hz}, {fmax_hz}")
    erb = np.linspace(erb_number(fmin_hz), erb_number(fmax_hz), int(n))
    anchors = np.asarray(anchors_hz, dtype=float).reshape(-1)
    if anchors.size:
        if np.any(~np.isfinite(anchors)) or anchors.min() < fmin_hz or anchors.max() > fmax_hz:
            raise ConfigError(f"anchors must lie within {fmin_hz}..{fmax_hz} Hz, got {anchors.tolist()}")
        slots = np.abs(erb[None, :] - erb_number(anchors)[:, None]).argmin(axis=1)
        if np.unique(slots).size != slots.size:
            raise ConfigError(f"anchors {anchors.tolist()} are too close together for {n} bins")
        erb[slots] = erb_number(anchors)
    freqs = (10.0 ** (erb / 21.4) - 1.0) / 0.00437
    bins = np.unique(np.rint(freqs * n_fft / sample_rate).astype(np.int64))
    if bins.size != n:
        raise ConfigError(f"{n} ERB-spaced bins do not fit between {fmin_hz} and {fmax_hz} Hz "
                          f"at {sample_rate / n_fft:.2f} Hz per bin")
    return tuple(int(b) for b in bins)


def harmonic_bins(f0_hz: float = 500.0, fmax_hz: float = 12000.0, *, fill: int = 12, fill_min_hz: float = 300.0,
                  fill_max_hz: float = 1800.0, min_gap: int = 4, n_fft: int = N_FFT,
                  sample_rate: int = SAMPLE_RATE) -> tuple[int, ...]:
    """The bins of every multiple of ``f0_hz`` up to ``fmax_hz``, plus ERB-spaced low bins.

    A harmonic sound of fundamental f0 has energy only at multiples of f0; a bank of a subset
    of bins localises it only through the harmonics that fall on a network. On the lattice
    of 500 Hz multiples lie all harmonics of 500, 1000 and 2000 Hz (the paper's test tones),
    while below 1.8 kHz, where interaural phase is unambiguous and carries the lateral angle,
    the lattice is sparse: ``fill`` ERB-spaced bins between ``fill_min_hz`` and
    ``fill_max_hz`` are added, except those within ``min_gap - 1`` bins of a lattice bin.

    Parameters
    ----------
    f0_hz : float
        Lattice spacing in Hz, > 2 bins.
    fmax_hz : float
        Highest lattice frequency in Hz, f0_hz..sample_rate / 2.
    fill : int
        ERB-spaced candidates of the low fill (0: none).
    fill_min_hz, fill_max_hz : float
        Band of the low fill, Hz.
    min_gap : int
        A fill bin closer than this many bins to a lattice bin is dropped (the Hamming
        window's main lobe is +-2 bins wide), >= 1.

    Returns
    -------
    tuple of int
        Increasing, distinct bin indices.
    """
    df = sample_rate / n_fft
    if not (np.isfinite(f0_hz) and f0_hz > 2 * df and f0_hz <= fmax_hz <= sample_rate / 2):
        raise ConfigError(f"need {2 * df:.1f} Hz < f0_hz <= fmax_hz <= {sample_rate / 2} Hz, got {f0_hz}, {fmax_hz}")
    if not isinstance(min_gap, (int, np.integer)) or min_gap < 1:
        raise ConfigError(f"min_gap must be an integer >= 1, got {min_gap!r}")
    lattice = np.rint(f0_hz * np.arange(1, int(fmax_hz // f0_hz) + 1) / df).astype(np.int64)
    low = np.asarray(erb_spaced_bins(fill, fill_min_hz, fill_max_hz, n_fft=n_fft, sample_rate=sample_rate)
                     if fill else (), np.int64)
    keep = [b for b in low if np.abs(lattice - b).min() >= min_gap]
    return tuple(int(b) for b in np.unique(np.concatenate([lattice, np.asarray(keep, np.int64)])))


def _real(value, what: str) -> float:
    """A finite float, or ConfigError naming ``what``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ConfigError(f"{what} must be finite, got {value!r}")
    return v


@dataclasses.dataclass(frozen=True, kw_only=True)
class SSDENetProfile:
    """Size and training recipe of an SSDENet bank.

    Parameters
    ----------
    name : str
        Profile name (part of the cache file name).
    hidden : int
        Units H of each of the two hidden layers (the paper: 500), 1-4096.
    bins : tuple of int
        rFFT bins (of the 2048-point ear front end, 21.53 Hz apart) that get a network;
        increasing, distinct, within 1..1024.
    sounds : int
        Random sounds per bin in the training set, each with one virtual source near every
        grid direction (the paper's profile: 1000, i.e. 327 000 examples per bin on the
        327-direction grid).
    epochs : int
        Passes over the training set, >= 1.
    batch_size : int
        Examples per bin in one Adam step, >= 1.
    learning_rate : float
        Adam step size, > 0.
    sigma_deg : float
        Width (deg) of the Gaussian target around the true direction, > 0.
    jitter_deg : float
        Radius (deg) of the cap around each grid direction within which each sound's
        virtual source is drawn, 0-30 (see
        :func:`~acoustic_sim.auditory.ssdenet.training.source_directions`); 0 puts every
        source on the measured direction nearest to its grid direction.
    snr_db : tuple of float
        Range (low, high) in dB of the uniform per-sound signal-to-noise ratio of the
        training spectra.
    seed : int
        Default seed of the training data and the initial weights (>= 0).
    threads : int
        torch intra-op threads while training (set for the duration of
        :func:`~acoustic_sim.auditory.ssdenet.training.train_weights` and restored afterwards);
        0 keeps the current setting. Same seed and same thread count give bit-identical
        weights.
    """

    name: str
    hidden: int
    bins: tuple[int, ...]
    sounds: int
    epochs: int = 1
    batch_size: int = 256
    learning_rate: float = 3e-3
    sigma_deg: float = 6.0
    jitter_deg: float = 6.0
    snr_db: tuple[float, float] = (10.0, 40.0)
    seed: int = 0
    threads: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(f"profile name must be a non-empty string, got {self.name!r}")
        where = f"profile {self.name!r}"
        for field, lo in (("hidden", 1), ("sounds", 1), ("epochs", 1), ("batch_size", 1), ("seed", 0), ("threads", 0)):
            v = getattr(self, field)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < lo:
                raise ConfigError(f"{where}: {field} must be an integer >= {lo}, got {v!r}")
            object.__setattr__(self, field, int(v))
        if self.hidden > 4096:
            raise ConfigError(f"{where}: hidden must be <= 4096, got {self.hidden}")
        try:
            bins = tuple(int(b) for b in self.bins)
        except (TypeError, ValueError):
            bins = ()
        if not bins or any(b < 1 or b >= N_BINS for b in bins) or any(a >= b for a, b in itertools.pairwise(bins)):
            raise ConfigError(f"{where}: bins must be increasing, distinct and within 1..{N_BINS - 1}, "
                              f"got {self.bins!r}")
        object.__setattr__(self, "bins", bins)
        for field, lo, hi in (("learning_rate", 0.0, math.inf), ("sigma_deg", 0.0, 180.0), ("jitter_deg", 0.0, 30.0)):
            v = _real(getattr(self, field), f"{where}: {field}")
            ok = (lo < v <= hi) if field != "jitter_deg" else (lo <= v <= hi)
            if not ok:
                raise ConfigError(f"{where}: {field} must be in {'[' if field == 'jitter_deg' else '('}{lo:g}, {hi:g}], "
                                  f"got {v}")
            object.__setattr__(self, field, v)
        try:
            snr = tuple(_real(v, f"{where}: snr_db") for v in self.snr_db)
        except TypeError:
            snr = ()
        if len(snr) != 2 or snr[0] > snr[1]:
            raise ConfigError(f"{where}: snr_db must be (low, high) in dB with low <= high, got {self.snr_db!r}")
        object.__setattr__(self, "snr_db", snr)

    @property
    def n_bins(self) -> int:
        """Number of networks in the bank."""
        return len(self.bins)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Centre frequencies (Hz) of the profile's bins, float64 (n_bins,)."""
        return bin_frequencies()[list(self.bins)]

    def n_parameters(self, n_directions: int) -> int:
        """Trainable parameters of the bank for a grid of ``n_directions``."""
        h = self.hidden
        return self.n_bins * ((N_FEATURES + 1) * h + (h + 1) * h + (h + 1) * n_directions)

    def to_dict(self) -> dict:
        """JSON-ready description (stored in checkpoints)."""
        d = dataclasses.asdict(self)
        d["bins"] = list(self.bins)
        d["snr_db"] = list(self.snr_db)
        return d


PAPER = SSDENetProfile(
    name="paper",
    hidden=500,
    bins=harmonic_bins(),
    sounds=1000,
    epochs=1,
    batch_size=256,
    learning_rate=3e-3,
    sigma_deg=6.0,
    jitter_deg=6.0,
)
"""The paper's network size (5 -> 500 -> 500 -> D: 0.42 M parameters per bin on the 327
grid, 13.4 M = 51 MiB for the bank) on 32 bins from 301 Hz to 11.99 kHz
(:func:`harmonic_bins`), trained on 1000 sounds per bin (327 000 examples, one epoch).

Bins: every multiple of 500 Hz up to 12 kHz (24 bins) and 8 ERB-spaced bins between 300 Hz
and 1.8 kHz. A harmonic sound is localised only through the harmonics that fall on a
network: on the 500 Hz lattice lie all harmonics of the paper's fundamentals (0.5, 1 and 2
kHz), densely enough above 2 kHz for the pinna's spectral cues, and the low ERB fill keeps
the interaural phase of lateral directions. Not all 544 bins of 300 Hz-12 kHz (the paper's
range): the frame budget and the training time are linear in the bins. A pure tone off the
lattice above 1.8 kHz meets no network: a bank of a subset of bins cannot localise every tone.

Training: ``sigma_deg=6``, ``jitter_deg=6``: every measured KEMAR direction (710, twice the
grid) is a virtual source, not only the 327 nearest to grid directions, so sources between
grid directions (where the renderer plays other measured HRIRs) are localised too.

Measurements (the bins and recipes compared): docs/notes/ssdenet_recipes.md.
"""

FAST = SSDENetProfile(
    name="fast",
    hidden=64,
    bins=harmonic_bins(),
    sounds=500,
    epochs=3,
    batch_size=64,
    learning_rate=1e-2,
    sigma_deg=6.0,
    jitter_deg=6.0,
    threads=1,
)
"""Small networks (5 -> 64 -> 64 -> D, 0.8 M parameters in all) on the paper profile's 32
bins (:func:`harmonic_bins`), trained like it on jittered virtual sources (``jitter_deg=6``,
``sigma_deg=6``): the bank of the tests and of the cabin tasks' regression tests. 500 sounds
per bin, 3 epochs (about 7 700 Adam steps of 64 examples at a learning rate of 0.01; one
thread, because its matrices are too small to gain from more, and one thread cannot stall
behind other jobs; ``acoustic-sim train ssdenet --profile fast``). The scripted ReverseAlarm
policy reads the alarm's lateral angle 22 deg off the median plane
(:class:`policies.scripted.ScriptedReverseAlarm`), where the 16-bin bank (:data:`QUICK`)
scatters; this is the cheapest recipe measured that meets the cabin targets for three
training seeds and the anechoic tests for the profile's seed.

Measurements (the recipes compared, training times, seed ranges): docs/notes/ssdenet_recipes.md.
"""

QUICK = dataclasses.replace(
    FAST,
    name="quick",
    bins=erb_spaced_bins(16, 300.0, 12000.0),
    sounds=200,
    epochs=2,
    sigma_deg=4.0,
    jitter_deg=0.0,
)
"""Small networks (5 -> 64 -> 64 -> D, 0.4 M parameters) on 16 ERB-spaced bins, 200 sounds,
2 epochs, virtual sources only at the measured directions nearest to the grid
(``jitter_deg=0``, the paper's setting), sigma 4 deg. Used by ``acoustic-sim eval paper
--quick``, which trains two banks (the ears' own and the measured HRTF's) and must finish
within 3 minutes; accurate for sources at grid directions but not between them, so not the
tasks' bank (:data:`FAST`). It was the ``fast`` profile until 2026-12-04. Measurements:
docs/notes/ssdenet_recipes.md."""

PROFILES: dict[str, SSDENetProfile] = {"paper": PAPER, "fast": FAST, "quick": QUICK}
"""The named profiles."""


def get_profile(profile) -> SSDENetProfile:
    """A profile by name (``"paper"``, ``"fast"``) or the profile itself."""
    if isinstance(profile, SSDENetProfile):
        return profile
    if isinstance(profile, str) and profile in PROFILES:
        return PROFILES[profile]
    raise ConfigError(f"unknown SSDENet profile {profile!r}; valid: {', '.join(PROFILES)}")
