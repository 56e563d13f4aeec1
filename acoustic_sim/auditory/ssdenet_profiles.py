"""SSDENet's bins and training recipes: which frequency bins get a network, and the profiles.

A bank of per-bin networks (:mod:`acoustic_sim.auditory.ssdenet`) localises a sound only
through the bins that have a network, so the choice of bins is part of a profile, beside the
network size and the training recipe. :data:`PAPER` is the paper's network size on 32
bins (:func:`harmonic_bins`; the reasons and measurements are in :data:`PAPER`'s
docstring), :data:`FAST` a small bank for tests and the tasks' regression tests, :data:`QUICK` a
smaller one for the quick paper evaluation. All are re-exported by :mod:`acoustic_sim.auditory.ssdenet`.
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
        :func:`~acoustic_sim.auditory.ssdenet_training.source_directions`); 0 puts every
        source on the measured direction nearest to its grid direction.
    snr_db : tuple of float
        Range (low, high) in dB of the uniform per-sound signal-to-noise ratio of the
        training spectra.
    seed : int
        Default seed of the training data and the initial weights (>= 0).
    threads : int
        torch intra-op threads while training (set for the duration of
        :func:`~acoustic_sim.auditory.ssdenet_training.train_bank` and restored afterwards);
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
and 1.8 kHz. Why not all 544 bins of 300 Hz-12 kHz (the paper's range): the budgets. One
frame costs about 0.045 ms per valid bin (the weights, 1.7 MB per bin, stream through the
cache once per frame), SSDENet has about 2-3 of the 4 ms frame budget it shares with
MelCNN, and training is linear in the bins (all 544 would take over two hours here and 230
M parameters, 0.9 GB). Why these 32: a harmonic sound is localised only through the
harmonics that fall on a network. The first bank had 32 ERB-spaced bins (nine moved onto
the audiometric frequencies): the odd harmonics of a 500 Hz square wave (0.5, 1.5, 2.5,
... kHz) met two of its networks, those of a 1 kHz one two, and SSDENet lost to MUSIC,
which uses every bin, on 9 of the paper's 13 test signals (triangle 500 Hz: 50.4 against
17.0 deg; square 500 Hz: 40.4 against 17.9; ``results/paper`` of 2026-11-22). On the 500
Hz lattice lie all harmonics of the paper's fundamentals (0.5, 1 and 2 kHz), and densely
enough above 2 kHz (13 bins in 6-12 kHz, where the pinna notches are) for the spectral
cues of front and back; the low ERB fill keeps the interaural phase of lateral directions,
unambiguous only below about 1.5 kHz, sampled every 65-200 Hz. The full ``eval paper`` run
(musashi ears, ``results/paper``, with the validity rule's leakage test,
:data:`~acoustic_sim.auditory.ssdenet.LEAKAGE`, and the product fusion of bins,
:data:`~acoustic_sim.auditory.ssdenet.FUSIONS`): SSDENet below MUSIC on all 13 signals
(triangle 500 Hz 1.7 against 17.0 deg, white noise 0.9 against 8.3; banks trained on this
machine's CPU, 2026-12-05); the narrowest margin is the 2 kHz sine (42.7 against 44.0), a
single bin, where the lattice changes nothing. The worst broadband signal is the 2 kHz
square wave, 9.9 deg: its harmonics up to 12 kHz meet three networks (2, 6 and 10 kHz).
Under the paper's sum of the bins' maps it was 20.8 deg, with a median of 0: the mean came
from cone-of-confusion mistakes (the same lateral angle, another elevation), where one of
the three bins' confident wrong peak outvoted the other two; the evidence was there (the
product of the three maps finds the direction). Before that was found, neither more
training nor more bins reached 15 deg under the sum: banks trained on those three bins alone
(109 directions; 1 or 2 epochs, 1000 or 3000 sounds) gave 17.7-24.3 deg for the square wave;
on the musashi ears (327 directions, a ``/tmp`` script, 2026-12-03) 21.3 deg, with a 14 kHz
network as well 24.0, with 14 and 18 kHz 19.7; ``jitter_deg=0`` 27.2, ``sigma_deg`` 3 23.1,
``sigma_deg`` 10 29.1 (against 21.3 with the profile's 6 and 6). A pure tone off the
lattice above 1.8 kHz (a 2.25 kHz sine, a voice's upper harmonics) meets no network, and one
below it only where the fill has a bin: a bank of a subset of bins cannot localise every
tone.

Training: ``sigma_deg=6``, ``jitter_deg=6``: every measured KEMAR direction (710, twice the
grid) is a virtual source, not only the 327 nearest to grid directions, so sources between
grid directions (where the renderer plays other measured HRIRs) are localised too. On 8
ERB-spaced bins (1 epoch): sources only on the grid gave 5.7 deg mean error on grid
directions but 24.8 deg over all 710 measured directions; jittered sources with sigma 6
gave 13.3 and 18.5 deg; sigma 4 with jitter 23.6 deg over all directions. Batches of 256
(1278 Adam steps) beat 512 (639 steps) at the same cost (18.5 against 19.8 deg). SNR
10-40 dB: the range in which bins are valid (10 dB above the noise); training down to 5 dB
made clean estimates worse (17 against 14 deg in a fast bank). Training time, frame time
and memory: ``acoustic-sim bench pipeline`` (``bench/pipeline.json``).
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
behind other jobs): 98 s of CPU time, 137 s with other jobs on both cores (``acoustic-sim
train ssdenet --profile fast``; the 16-bin bank: 13-17 s).

Why this recipe (since 2026-12-04, session 21; before, 16 ERB-spaced bins, 200 sounds, 2
epochs, sources only at grid directions, now :data:`QUICK`): under the line-of-sight law
for outside sounds (:func:`tasks.soundscape.outside_placement`) the scripted ReverseAlarm
policy reads the alarm's lateral angle 22 deg off the median plane
(:class:`policies.scripted.ScriptedReverseAlarm`), where the 16-bin bank's estimates
scatter (10 of 20 on the test seeds 100-119). Measured with that law and policy (a ``/tmp``
script; test seeds 100-119, training seeds 0, 1 and 2; anechoic: KEMAR, white noise through
the HRTF, ``grid`` the grid test of ``tests/test_ssdenet.py``, ``all`` the 710 measured
directions, ``five`` its five rendered directions, each of which must be within 20 deg):

| recipe (training time, other core busy) | ReverseAlarm /20 | ParkingBrake /20 | anechoic mean error, deg |
|---|---|---|---|
| 16 ERB bins, 200 sounds, 2 epochs (:data:`QUICK`, 17 s) | 10 (seed 0) | 18 / 19 / 19 | grid 4.7, all 20.7 |
| 32 bins, jittered, 200 sounds, 2 epochs (30 s) | not measured | 19 / 19 / 19 | grid 23.2; two of five beyond 20 |
| the same, 400 sounds, 3 epochs (79 s) | 18 / 20 / 18 | 19 / 19 / 19 | grid 8.9 / 8.8 / 6.1, all 13.1 / 12.9 / 10.5; seed 0: one of five at 57 |
| **the same, 500 sounds, 3 epochs (this profile; 98 s CPU)** | **19 / 20 / 18** | **19 / 18 / 19** | grid 5.0 / 7.0 / 5.6, all 8.8 / 10.9 / 10.6; seed 2: one of five at 53 |
| the same, 600 sounds, 4 epochs (150 s) | 19 / 19 / 20 | 18 / 19 / 19 | grid 4.9 / 4.1 / 3.0, all 8.6 / 9.0 / 7.0 |

No false release in ReverseAlarm with any of the 32-bin banks; in ParkingBrake (which the
law does not touch) one with the 600-sound bank of seed 0 (115). On seeds 1000-1099
(training seed 0): this profile ReverseAlarm 95 with none, ParkingBrake 90 with 3 false
releases; the 600-sound bank ReverseAlarm 90 with none, ParkingBrake 89 with 4; the
400-sound bank ParkingBrake 92 with 1; the 16-bin bank ReverseAlarm 73 with none (89 with
none under the old law and policy), ParkingBrake 89 with 1. Every recipe lets go falsely
in 0-4 % of those episodes, and the cheaper 32-bin ones put one of the five anechoic
directions at its front-back mirror for some training seed, so 20 episodes without a false
release, and five directions within 20 deg, are draws, not properties of a recipe: this
one meets the cabin targets for all three seeds and the anechoic tests for the profile's
seed (0), at about two thirds of the 600-sound recipe's cost. It is trained once per test
run (the kemar bank; ``eval paper --quick`` takes :data:`QUICK`).

Earlier measurements (before the line-of-sight law, with the then policy's front sectors),
kept for whoever changes the recipe again. The 16-bin bank's virtual sources sit exactly on
the measured directions nearest to the grid directions (``jitter_deg=0``, the paper's
setting, where measurement and estimation directions are the same), so it is accurate for
sources at grid directions (KEMAR, white noise through the HRTF: mean error 4.1 deg over the
grid, 1.9 deg off the median plane, 94 % within 20 deg) but not between them (21 deg over
all 710 measured directions). sigma 4 deg: sharp targets train faster in a small network
(sigma 12, 8, 6, 4 deg gave 17, 11, 7, 4 deg). 2044 Adam steps of 64 examples at a learning
rate of 0.01; one thread, because its matrices are too small to gain from more, and one
thread cannot stall behind other jobs on a busy machine.

Variants measured in the cabin tasks, where the regression tests used the 16-bin bank then
(scripted policies, test seeds 100-119 with training seeds 0, 1 and 2, and seeds 1000-1099;
a ``/tmp`` script, 2026-12-04). The 16-bin bank (:data:`QUICK`): ReverseAlarm 18, 15 and 14
of 20, each with one false release, ParkingBrake 18, 19 and 19 with none; on 1000-1099
ReverseAlarm 89 with none (training seed 0) and 78 with 1 (seed 1), ParkingBrake 89 with 1.
Jittered sources as in the paper profile (``jitter_deg=6``, ``sigma_deg=6``, the same
training time): ReverseAlarm 19 of 20 with none for all three seeds, ParkingBrake 18, 19 and
19 with none; on 1000-1099 ReverseAlarm 90 with none and ParkingBrake 91 with 1 for seeds 0
and 1 alike; but white noise through KEMAR's HRIRs at the grid directions (rendered as
``tests/test_ssdenet.py``'s grid test does) 21.4 deg mean error (14.6 off the median plane,
81 % within 20 deg), against the 16-bin bank's 4.7 (0.5, 99 % that way), and 24.1 against
20.7 over all 710 measured directions: the accuracy that the unit tests and issue 3's
anechoic test check. The same with 400 sounds and 3 epochs (35 s): 14.4 (8.9, 88 %) and 18.6
deg, but ReverseAlarm 18 and 19 of 20 (seeds 0, 1) and 85 on 1000-1099. ``sigma_deg=6``
alone: ReverseAlarm 18 with one false release and 19 with none (seeds 0, 1), 86 with 1 on
1000-1099 (seed 1). The paper profile's 32 bins at this size (twice the training time):
ReverseAlarm 19, 19 and 18 with none, ParkingBrake 19, 19 and 16; on 1000-1099 93 with 2
false releases and 92 with 1. The paper's 32 bins with jittered sources (2026-12-04, a fresh
machine; ``grid`` is the grid test above, ``all`` the 710 measured directions, ``five`` the
five rendered directions of ``tests/test_ssdenet.py``, which must each be within 20 deg;
times with another job on the other core): 200 sounds, 2 epochs (26-33 s): ReverseAlarm 19,
19 and 20 of 20 and ParkingBrake 19, 19 and 19, none with a false release, but grid 23.2
deg, all 24.1, two of the five beyond 20 deg (training seed 0); at H=128 (55 s) grid 23.9
(seed 0). The 16 bins, jittered, at H=128 (28-30 s): ReverseAlarm 19, 19 and 18 (one false
release), ParkingBrake 18, 19 and 19, grid 22.6, 20.4 and 19.4. The 32 bins, jittered, 400
sounds, 3 epochs (79 s): 19, 19, 19 and 19, 19, 19 with none, grid 8.9, 8.8 and 6.1 deg, all
13.1, 12.9 and 10.5, but seed 0's bank puts (150, 30) at its front-back mirror (57 deg); on
1000-1099 ReverseAlarm 88 with 1 false release (seed 0) and 96 with 1 (seed 1), ParkingBrake
92 with 1 and 91 with 2. 600 sounds, 4 epochs (150 s): grid 4.9, 4.1 and 3.0, all 8.6, 9.0
and 7.0 deg, the five within 12 deg, but on the test seeds ReverseAlarm 18 of 20 with one
false release (seed 0), 19 and 19, ParkingBrake 18 with one, 19 and 19, and on 1000-1099
ReverseAlarm 91 with 3 (seed 0) and 91 with 1 (seed 1), ParkingBrake 89 with 4 and 90 with
3. A better localiser in the anechoic tests is not a better one in the cabin, and every
variant lets go falsely in 1-4 % of episodes there, so 20 episodes with none is a draw, not
a property of a recipe. None is better in the tasks for every training seed and in the
anechoic tests, so session 20 kept the 16-bin bank (the 79 s and 150 s recipes would also be trained three
times per test run: the kemar bank and the quick paper evaluation's two), and the tests'
cabin targets stayed expected failures with a floor (``tests/test_policies.py``) until the
line-of-sight law and the lateral rule (above).
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
(``jitter_deg=0``, the paper's setting), sigma 4 deg: trains in 13-17 s. Used by
``acoustic-sim eval paper --quick``, which trains two banks (the ears' own and the measured
HRTF's) and must finish within 3 minutes; accurate for sources at grid directions (KEMAR,
white noise: 4.1-4.7 deg mean error over the grid) but not between them (21 deg over all
710 measured directions), so not the tasks' bank (:data:`FAST`). It was the ``fast``
profile until 2026-12-04."""

PROFILES: dict[str, SSDENetProfile] = {"paper": PAPER, "fast": FAST, "quick": QUICK}
"""The named profiles."""


def get_profile(profile) -> SSDENetProfile:
    """A profile by name (``"paper"``, ``"fast"``) or the profile itself."""
    if isinstance(profile, SSDENetProfile):
        return profile
    if isinstance(profile, str) and profile in PROFILES:
        return PROFILES[profile]
    raise ConfigError(f"unknown SSDENet profile {profile!r}; valid: {', '.join(PROFILES)}")
