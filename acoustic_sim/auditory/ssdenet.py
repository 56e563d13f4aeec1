"""SSDENet: one small network per frequency bin, mapping ILD/IPD to a direction-existence map.

The paper (section "Human Mimetic Sound Source Direction Estimation") gives each discrete
frequency w_i its own network SSDENet_i: 5 inputs (ILD and the two unit phasors of
:func:`acoustic_sim.auditory.features.ild_ipd`), two hidden layers and one output per
direction d_k of the grid, all with sigmoid activations::

    P(w_i)  = SSDENet_i(ILD(w_i), IPD(w_i))                 (D,)
    P(d_k)  = sum_i c_i P(d_k, w_i),   c_i = 1 if w_i is valid else 0
    d^      = argmax_k P(d_k)

Fusion (:data:`FUSIONS`)
    The paper's sum over valid bins is ``fusion="sum"``; the default is ``"product"``, n
    times the geometric mean of the valid bins' maps (:func:`fuse`), which a bin that is
    confidently wrong cannot outvote (measurements: docs/notes/fusion.md).

Batched bank
    The networks of all chosen bins are stored as stacked weights ``w1 (n_bins, 5, H)``,
    ``w2 (n_bins, H, H)``, ``w3 (n_bins, H, D)`` (biases ``(n_bins, 1, .)``) and evaluated
    together by three ``torch.baddbmm`` calls (:func:`ssdenet_forward`), never by a loop
    over bins. Adam is element-wise and the loss is the sum of the per-bin mean squared
    errors, so training the stack is exactly training each network on its own.

Training
    :mod:`acoustic_sim.auditory.ssdenet_training`: virtual sources through the HRTF (the
    paper's equations), Gaussian targets, MSE loss, Adam.

Profiles (:data:`PROFILES`)
    :mod:`acoustic_sim.auditory.ssdenet_profiles` (re-exported here): :class:`SSDENetProfile`
    and the ``paper`` / ``fast`` / ``quick`` entries: the paper's network size on a measured
    subset of bins, a small one for tests and the tasks' regression tests, and a smaller one
    for the quick paper evaluation.

Checkpoints
    Trained banks are cached per (HRTF ident, grid ident, profile) by
    :meth:`SSDENetBank.load_or_train`, through :mod:`acoustic_sim.auditory.checkpoint`.

Use::

    hrtf = HRTF.load("kemar")
    grid = DirectionGrid.paper(hrtf)
    bank = SSDENetBank.load_or_train(hrtf, grid, "paper")   # trained once (minutes), then cached
    spectra = analyze(audio).spectra                         # (K, 2, 1025)
    valid = valid_bins(spectra, noise_power, class_bins=characteristic_bins)
    est = bank.estimate(spectra, valid)                      # None: no bank bin was valid
    existence, vector, (azimuth_deg, elevation_deg) = est
"""

from __future__ import annotations

import functools
import math
from collections import OrderedDict
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from acoustic_sim.auditory import checkpoint as ckpt
from acoustic_sim.auditory.features import ild_ipd
from acoustic_sim.auditory.frontend import N_BINS, N_FFT, bin_frequencies, leakage_envelope
from acoustic_sim.auditory.ssdenet_profiles import (  # noqa: F401 (the profiles, re-exported here)
    AUDIOMETRIC_HZ,
    FAST,
    N_FEATURES,
    PAPER,
    PROFILES,
    QUICK,
    SSDENetProfile,
    erb_number,
    erb_spaced_bins,
    get_profile,
    harmonic_bins,
)
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

KIND = "ssdenet"
"""Checkpoint kind."""

VERSION = 1
"""Version of the training recipe; a cached bank of another version is retrained."""


GATHER_MAX_BINS = 4
"""Largest subset of bins whose weights :meth:`SSDENetBank.existence` gathers; a larger one
runs the whole bank (contiguous weights, memory-bound). Measured with the paper bank (32
bins, H = 500, 2 threads): gathering 6 bins and running them 1.48 ms, 16 bins 3.36 ms, the
whole bank 1.34 ms; 2 bins 0.68 ms."""

WITHIN_MAX_BINS = 16
"""Largest set of bins whose gathered weights :meth:`SSDENetBank.existence` keeps for reuse
(``within=``: a detected class's characteristic bins); larger sets are not cached."""

WITHIN_CACHE = 8
"""Gathered weight sets kept (least recently used dropped): at most 8 x 16 x 1.7 MB for
the paper bank."""

FUSIONS = ("product", "sum")
"""How the existence maps of several bins make one P(d) (:func:`fuse`).

``"sum"``
    The paper's equation, P(d) = sum_i P(d, w_i).
``"product"``
    n times the geometric mean, P(d) = n exp(mean_i log max(P(d, w_i), FUSION_FLOOR)): the
    bins as independent pieces of evidence (a direction must be likely at every bin), the
    factor n weighting a frame by its number of valid bins when frames are summed, as the
    sum does.

Why the product is the default: under the sum a bin whose network is confidently wrong
outvotes the others, which matters most when few bins are valid (a square wave at 2 kHz
meets three of the paper bank's 32 bins). The floor keeps one bin's exact zero from vetoing
a direction.

Frames are still summed (each frame's fused map, :meth:`SSDENetBank.estimate`, the
pipeline's evidence window): a frame that holds another sound, or mostly reverberation,
would veto the right direction under a product over frames as well. The pipeline's onset
windows, several looks at one first wavefront, are pooled by :func:`pool_looks` like the
bins: their geometric mean under the product.

Measurements (simulation, room, tasks; the floor): docs/notes/fusion.md.
"""

DEFAULT_FUSION = "product"
"""The fusion :class:`SSDENetBank` and the pipeline use unless told (:data:`FUSIONS`).

ParkingBrake keeps the sum (:attr:`tasks.parking_brake.ParkingBrakeEnv.fusion`), where
the product measured worse. The sum stays available everywhere as ``fusion="sum"``
(``acoustic-sim localize --fusion sum``), and ``eval paper`` reports both. Measurements:
docs/notes/fusion.md."""

FUSION_FLOOR = 1e-4
"""Floor of each bin's P(d, w_i) under the product fusion (:data:`FUSIONS`)."""


def check_fusion(fusion: str) -> str:
    """``fusion`` if it is one of :data:`FUSIONS`, else a :class:`ConfigError`."""
    if fusion not in FUSIONS:
        raise ConfigError(f"unknown fusion {fusion!r}; valid: {', '.join(FUSIONS)}")
    return fusion


def fuse(existence, select, fusion: str = DEFAULT_FUSION) -> np.ndarray:
    """Fuse the existence maps of bins into P(d), for several selections of the bins at once.

    Parameters
    ----------
    existence : array_like, float (..., n, D)
        P(d, w_i) of n bins.
    select : array_like, bool or 0/1 (..., c, n)
        Which bins each of c selections uses (a frame's valid bins, a class's characteristic
        bins).
    fusion : str
        ``"product"`` or ``"sum"`` (:data:`FUSIONS`).

    Returns
    -------
    numpy.ndarray, float32 (..., c, D)
        Zero for a selection of no bin.
    """
    check_fusion(fusion)
    p = np.asarray(existence, np.float32)
    w = np.asarray(select).astype(np.float32)
    if fusion == "sum":
        return np.matmul(w, p)
    n = w.sum(axis=-1, keepdims=True)  # (..., c, 1)
    logs = np.matmul(w, np.log(np.maximum(p, np.float32(FUSION_FLOOR))))
    return np.where(n > 0, n * np.exp(logs / np.maximum(n, 1.0)), 0.0).astype(np.float32)


def pool_looks(existence, fusion: str = DEFAULT_FUSION) -> np.ndarray:
    """One existence map per bin from k looks at the same sound (onset windows).

    ``existence`` (k, ..., D) -> (..., D): the mean over the looks under the sum, their
    geometric mean (floored as in :func:`fuse`) under the product.
    """
    check_fusion(fusion)
    p = np.asarray(existence, np.float32)
    if fusion == "sum":
        return p.mean(axis=0)
    return np.exp(np.log(np.maximum(p, np.float32(FUSION_FLOOR))).mean(axis=0)).astype(np.float32)


# ------------------------------------------------------------------------------------------
# The functional core
# ------------------------------------------------------------------------------------------

PARAMETER_NAMES = ("w1", "b1", "w2", "b2", "w3", "b3")


INIT_GAINS = (4.0, 8.0, 1.0)
"""Initial weight scale of layers 1, 2, 3 relative to ``torch.nn.Linear``'s 1/sqrt(fan_in).

With ``nn.Linear``'s init the second hidden layer's pre-activations spread by only about
0.08 whatever H is, so the sigmoids act as linear units, every hidden unit sees nearly the
same value, and training sits on a plateau where the outputs predict the mean target
(measured: no progress in 1200 Adam steps). The interaural phase is only useful through a
product of the two phasors (the source phase is random), which a linear layer cannot form.
Gains 4 and 8 put the first two layers' pre-activations at a spread of about 2 and 0.6,
inside the non-linear range of the sigmoid; on 2 test bins this halved the loss gap to the
plateau within the first 150 steps and gave a lower loss at every later step.
"""


def init_weights(n_bins: int, hidden: int, n_outputs: int, generator: torch.Generator, *,
                 output_prior: float = 0.5) -> dict[str, torch.Tensor]:
    """Initial stacked weights, float32.

    The weights and biases of layer l (fan-in ``fan_in``) are uniform in
    ``+-INIT_GAINS[l] / sqrt(fan_in)`` (:data:`INIT_GAINS`), except the output biases,
    which are ``logit(output_prior)``: starting the outputs at the mean target (about 0.03
    for a 12 deg Gaussian on the 327-direction grid) instead of 0.5 skips the first phase
    of training, in which every output is pushed down and the hidden layers learn nothing.

    Parameters
    ----------
    n_bins, hidden, n_outputs : int
        Stack size, hidden units H, outputs D.
    generator : torch.Generator
        The only source of randomness.
    output_prior : float
        Initial value of every output, in (0, 1).

    Returns
    -------
    dict of str to torch.Tensor
        ``w1 (n_bins, 5, H)``, ``b1 (n_bins, 1, H)``, ``w2 (n_bins, H, H)``,
        ``b2 (n_bins, 1, H)``, ``w3 (n_bins, H, D)``, ``b3 (n_bins, 1, D)``.
    """
    if not 0.0 < output_prior < 1.0:
        raise ConfigError(f"output_prior must be in (0, 1), got {output_prior}")
    shapes = {"w1": (N_FEATURES, hidden), "b1": (1, hidden), "w2": (hidden, hidden), "b2": (1, hidden),
              "w3": (hidden, n_outputs), "b3": (1, n_outputs)}
    fan_in = {"1": N_FEATURES, "2": hidden, "3": hidden}
    out = {}
    for name in PARAMETER_NAMES:
        layer = name[1]
        bound = INIT_GAINS[int(layer) - 1] / math.sqrt(fan_in[layer])
        t = torch.empty((n_bins,) + shapes[name], dtype=torch.float32)
        out[name] = t.uniform_(-bound, bound, generator=generator)
    out["b3"].fill_(math.log(output_prior / (1.0 - output_prior)))
    return out


def ssdenet_forward(x: torch.Tensor, w1: torch.Tensor, b1: torch.Tensor, w2: torch.Tensor, b2: torch.Tensor,
                    w3: torch.Tensor, b3: torch.Tensor) -> torch.Tensor:
    """Existence maps of a stack of SSDENets, all bins in three batched matrix products.

    Parameters
    ----------
    x : torch.Tensor, shape (n_bins, N, 5)
        ILD/IPD features, N examples (frames) per bin.
    w1, b1, w2, b2, w3, b3 : torch.Tensor
        Stacked weights ``(n_bins, 5, H)``, ``(n_bins, 1, H)``, ``(n_bins, H, H)``,
        ``(n_bins, 1, H)``, ``(n_bins, H, D)``, ``(n_bins, 1, D)``.

    Returns
    -------
    torch.Tensor, shape (n_bins, N, D)
        Sound-source existence P(d_k, w_i) in (0, 1).
    """
    h = torch.sigmoid(torch.baddbmm(b1, x, w1))
    h = torch.sigmoid(torch.baddbmm(b2, h, w2))
    return torch.sigmoid(torch.baddbmm(b3, h, w3))


# ------------------------------------------------------------------------------------------
# Inference helpers
# ------------------------------------------------------------------------------------------


def _bin_mask(spec, n_bins: int, what: str) -> np.ndarray:
    """A bool mask (..., n_bins) from a bool mask or integer bin indices."""
    m = np.asarray(spec)
    if m.dtype == bool:
        if m.shape[-1:] != (n_bins,):
            raise ConfigError(f"{what} mask must have {n_bins} bins on its last axis, got shape {m.shape}")
        return m
    if m.size == 0:
        return np.zeros(n_bins, bool)
    if not np.issubdtype(m.dtype, np.integer) or m.ndim != 1:
        raise ConfigError(f"{what} must be a bool mask over the {n_bins} bins or a 1-D array of bin indices, "
                          f"got dtype {m.dtype}, shape {m.shape}")
    if m.min() < 0 or m.max() >= n_bins:
        raise ConfigError(f"{what} indices must lie in 0..{n_bins - 1}, got {m.min()}..{m.max()}")
    out = np.zeros(n_bins, bool)
    out[m] = True
    return out


def _check_spectra(spectra) -> np.ndarray:
    x = np.asarray(spectra)
    if x.ndim < 2 or x.shape[-2] != 2:
        raise ConfigError(f"spectra must have shape (..., 2, n_bins) (left, right), got {x.shape}")
    if not np.issubdtype(x.dtype, np.number):
        raise ConfigError(f"spectra must be numbers, got dtype {x.dtype}")
    if not np.all(np.isfinite(x)):
        raise ConfigError("spectra contain NaN or inf")
    return x


def noise_power_spectrum(spectra) -> np.ndarray:
    """Mean power per ear and bin of noise-only frames, for :func:`valid_bins`.

    Parameters
    ----------
    spectra : array_like, complex (K, 2, n_bins) or (2, n_bins)
        Front-end spectra of a recording of the noise alone (e.g. the robot's driving noise).

    Returns
    -------
    numpy.ndarray, float64 (2, n_bins)
        Mean |X|^2 over the frames (full-scale units squared).
    """
    x = _check_spectra(spectra)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[0] == 0:
        raise ConfigError(f"noise spectra must have shape (K >= 1, 2, n_bins), got {x.shape}")
    return np.mean(np.abs(x.astype(np.complex128)) ** 2, axis=0)


def valid_bins(spectra, noise_power, factor: float = 10.0, class_bins=None, *, leakage: float = 0.0) -> np.ndarray:
    """The paper's valid bins c_i: power above ``factor`` times the noise, within a class's bins.

    Parameters
    ----------
    spectra : array_like, complex (..., 2, n_bins)
        Front-end spectra (left, right) of one or more frames.
    noise_power : float or array_like broadcastable to (2, n_bins)
        Power spectrum per ear of the noise the threshold refers to (the paper: the robot's
        driving noise; e.g. :func:`noise_power_spectrum`), in the units of ``|X|^2``, >= 0.
    factor : float
        A bin is valid when ``|X_l|^2 + |X_r|^2 > factor * (N_l + N_r)`` (the paper: 10,
        i.e. 10 dB above the noise), > 0.
    class_bins : array_like, optional
        The characteristic bins of the detected sound class (MelCNN): a bool mask over the
        n_bins bins or integer bin indices. Valid bins are intersected with them.
    leakage : float
        0 (the paper's rule alone) or a factor > 0: a bin is valid only when its power also
        exceeds ``leakage`` times the most that the Hamming window's sidelobes of any other
        bin of the frame can put there (:func:`~acoustic_sim.auditory.frontend.leakage_envelope`).
        See :data:`LEAKAGE` for why and what it measured. Only the bins that pass the other
        tests are checked, so ``class_bins`` (e.g. a bank's bins) keeps this cheap.

    Returns
    -------
    numpy.ndarray, bool (..., n_bins)
        Silent bins are never valid (the comparison is strict).
    """
    x = _check_spectra(spectra)
    n_bins = x.shape[-1]
    if not (np.isfinite(factor) and factor > 0):
        raise ConfigError(f"factor must be a finite number > 0, got {factor}")
    noise = np.asarray(noise_power, dtype=float)
    try:
        noise = np.broadcast_to(noise, (2, n_bins))
    except ValueError:
        raise ConfigError(f"noise_power must broadcast to (2, {n_bins}), got shape {noise.shape}") from None
    if not np.all(np.isfinite(noise)) or np.any(noise < 0):
        raise ConfigError("noise_power must be finite and >= 0")
    power = np.abs(x[..., 0, :].astype(np.complex128)) ** 2 + np.abs(x[..., 1, :].astype(np.complex128)) ** 2
    valid = power > factor * (noise[0] + noise[1])
    if class_bins is not None:
        valid = valid & _bin_mask(class_bins, n_bins, "class_bins")
    if not (np.isfinite(leakage) and leakage >= 0):
        raise ConfigError(f"leakage must be a finite number >= 0, got {leakage}")
    if leakage > 0:
        valid = valid & _free_of_leakage(power, valid, leakage, n_fft=2 * (n_bins - 1))
    return valid


LEAKAGE = 10.0
"""The leakage factor of the project's estimators (:func:`valid_bins`; the pipeline's and
``eval paper``'s SSDENet): a bin must hold 10 times (10 dB) more power than any other bin's
sidelobes can leak into it, the paper's margin over the noise applied to the window's own
leakage.

Why: a network interprets the ILD/IPD of its bin as a source at its frequency. Next to a
strong tone the window's sidelobes (-41 dB and below) fill the neighbouring bins with the
tone's own interaural phasors, far above the paper's noise threshold (a test tone 40 dB
over the sensor noise has about 69 dB of SNR in its peak bin), so the 624-1507 Hz networks
read a 1 kHz tone's IPD as a 624 Hz source's, and vote for the wrong directions.
Measurements (the factor and the alternatives compared): docs/notes/ssdenet_recipes.md."""


_LEAKAGE_CHUNK = 1 << 22
"""Elements of the (frames, bins, bins) products computed at once by :func:`_free_of_leakage`."""


@functools.lru_cache(maxsize=2)
def _leakage_matrix(n_fft: int) -> np.ndarray:
    """(n_bins, n_bins) float64: the envelope of the leakage from bin j into bin i (8 MB for 1025 bins)."""
    env = leakage_envelope(n_fft)
    n = env.size
    m = env[np.abs(np.arange(n)[:, None] - np.arange(n)[None, :])]
    m.setflags(write=False)
    return m


def _free_of_leakage(power: np.ndarray, candidates: np.ndarray, factor: float, n_fft: int) -> np.ndarray:
    """power (..., n_bins), candidates bool (..., n_bins) -> bool (..., n_bins): the candidate
    bins whose power exceeds ``factor`` times the sidelobe leakage of every other bin."""
    out = np.zeros(candidates.shape, bool)
    flat_p = power.reshape(-1, power.shape[-1])
    flat_c = candidates.reshape(-1, power.shape[-1])
    flat_o = out.reshape(-1, power.shape[-1])
    cols = np.flatnonzero(flat_c.any(axis=0))
    if cols.size == 0:
        return out
    spread = _leakage_matrix(n_fft)[cols]  # (n_cols, n_bins): leakage from every bin into each column
    step = max(1, _LEAKAGE_CHUNK // spread.size)
    for lo in range(0, flat_p.shape[0], step):
        p = flat_p[lo:lo + step]
        leak = np.max(p[:, None, :] * spread[None], axis=-1)  # (frames, n_cols)
        flat_o[lo:lo + step, cols] = flat_c[lo:lo + step][:, cols] & (p[:, cols] > factor * leak)
    return out


class DirectionEstimate(NamedTuple):
    """A direction estimate: unpacks as ``(existence, vector, (azimuth_deg, elevation_deg))``.

    Attributes
    ----------
    existence : numpy.ndarray, float32 (D,)
        P(d_k): the existence maps fused over the valid bins (:func:`fuse`) and summed over frames.
    vector : numpy.ndarray, float64 (3,)
        Unit vector of the most likely grid direction (head frame).
    angles_deg : tuple of float
        (azimuth, elevation) of ``vector`` in deg.
    """

    existence: np.ndarray
    vector: np.ndarray
    angles_deg: tuple[float, float]

    @property
    def azimuth_deg(self) -> float:
        return self.angles_deg[0]

    @property
    def elevation_deg(self) -> float:
        return self.angles_deg[1]


# ------------------------------------------------------------------------------------------
# The bank
# ------------------------------------------------------------------------------------------


class SSDENetBank(nn.Module):
    """SSDENets for a set of frequency bins, trained for one HRTF and one direction grid.

    Parameters
    ----------
    grid : DirectionGrid
        The D output directions.
    bins : sequence of int
        The rFFT bins (2048-point front end) that have a network, increasing.
    hidden : int
        Hidden units H per layer.
    hrtf_ident : str
        Ident of the HRTF the bank is (to be) trained on; checked on load.
    hrtf_name : str
        Human-readable HRTF name (messages only).
    profile : SSDENetProfile, optional
        The profile it was built from (stored in checkpoints).
    generator : torch.Generator, optional
        Draws the initial weights (default: a generator seeded with 0).
    output_prior : float
        Initial value of the outputs (:func:`init_weights`), in (0, 1).
    seed : int, optional
        The seed it was trained with (recorded in checkpoints).

    Notes
    -----
    Use :meth:`load_or_train` rather than the constructor.
    """

    def __init__(self, grid: DirectionGrid, bins, hidden: int, *, hrtf_ident: str, hrtf_name: str = "",
                 profile: SSDENetProfile | None = None, generator: torch.Generator | None = None,
                 output_prior: float = 0.5, seed: int | None = None) -> None:
        super().__init__()
        bins = np.asarray(bins, dtype=np.int64)
        if bins.ndim != 1 or bins.size == 0 or bins.min() < 1 or bins.max() >= N_BINS or np.any(np.diff(bins) <= 0):
            raise ConfigError(f"bins must be increasing bin indices within 1..{N_BINS - 1}, got {bins.tolist()}")
        if not isinstance(grid, DirectionGrid):
            raise ConfigError(f"grid must be a DirectionGrid, got {type(grid).__name__}")
        self.grid = grid
        self.bins = bins
        self.bins.flags.writeable = False
        self.hidden = int(hidden)
        self.hrtf_ident = str(hrtf_ident)
        self.hrtf_name = str(hrtf_name)
        self.profile = profile
        self.seed = seed
        gen = generator if generator is not None else torch.Generator().manual_seed(0)
        for name, t in init_weights(bins.size, self.hidden, len(grid), gen, output_prior=output_prior).items():
            setattr(self, name, nn.Parameter(t))
        self._gathered: OrderedDict = OrderedDict()  # (positions, weight versions) -> gathered weights

    # -- shape facts ------------------------------------------------------------------------

    @property
    def n_bins(self) -> int:
        """Number of networks."""
        return int(self.bins.size)

    @property
    def n_directions(self) -> int:
        """Outputs per network D."""
        return len(self.grid)

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Centre frequencies (Hz) of the bank's bins, (n_bins,)."""
        return bin_frequencies()[self.bins]

    def n_parameters(self) -> int:
        """Number of trainable parameters."""
        return int(sum(p.numel() for p in self.parameters()))

    def _weights(self) -> tuple[torch.Tensor, ...]:
        return tuple(getattr(self, n) for n in PARAMETER_NAMES)

    # -- evaluation -------------------------------------------------------------------------

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Existence maps of every bank bin.

        Parameters
        ----------
        x : torch.Tensor, float32 (n_bins, N, 5)
            ILD/IPD features of N examples at each of the bank's bins (bins first).

        Returns
        -------
        torch.Tensor, float32 (n_bins, N, D)
            P(d_k, w_i) in (0, 1).
        """
        if x.ndim != 3 or x.shape[0] != self.n_bins or x.shape[2] != N_FEATURES:
            raise ConfigError(f"SSDENet input must have shape ({self.n_bins}, N, {N_FEATURES}), got {tuple(x.shape)}")
        return ssdenet_forward(x, *self._weights())

    def existence(self, features, subset=None, within=None) -> np.ndarray:
        """Per-bin existence maps of ILD/IPD features.

        Parameters
        ----------
        features : array_like, float (..., n, 5)
            :func:`~acoustic_sim.auditory.features.ild_ipd` at the bank's bins
            (``spectra[..., bank.bins]``, n = n_bins), or at ``bank.bins[subset]``.
        subset : array_like of int, optional
            Positions (0..n_bins-1, increasing or not) of the bank bins the features belong
            to; default all. Up to :data:`GATHER_MAX_BINS` bins, only those networks run,
            on their weights gathered first (1.7 MB per bin); for more, the whole bank runs
            and the subset's outputs are kept (faster, and the same numbers to float32
            rounding).
        within : array_like of int, optional
            Positions of a set of bins that contains ``subset`` and recurs from call to
            call (the streaming pipeline passes the detected classes' characteristic bins,
            while the valid subset changes every frame). Up to :data:`WITHIN_MAX_BINS`
            bins, the networks of ``within`` run on their weights gathered once and kept
            (:data:`WITHIN_CACHE` sets), and the subset's outputs are kept: the copy,
            which costs as much as running the networks, is paid once per set instead of
            once per call (paper bank, 6 of a 16-bin set: 0.8 ms, against 1.2 ms gathering
            the 6 every call and 1.5 ms for the whole bank). The numbers are the same.

        Returns
        -------
        numpy.ndarray, float32 (..., n, D)
        """
        weights = self._weights()
        n = self.n_bins
        idx = None
        if subset is not None:
            idx = np.asarray(subset)
            if idx.ndim != 1 or not np.issubdtype(idx.dtype, np.integer) or (idx.size and (
                    idx.min() < 0 or idx.max() >= self.n_bins)):
                raise ConfigError(f"subset must be 1-D positions within 0..{self.n_bins - 1}, got {subset!r}")
            n = idx.size
        f = np.asarray(features, dtype=np.float32)
        if f.ndim < 2 or f.shape[-2:] != (n, N_FEATURES):
            raise ConfigError(f"features must have shape (..., {n}, {N_FEATURES}), got {f.shape}")
        if not np.all(np.isfinite(f)):
            raise ConfigError("features contain NaN or inf")
        lead = f.shape[:-2]
        if n == 0:
            return np.zeros(lead + (0, self.n_directions), np.float32)
        keep = None
        outer = None if within is None else self._within(within, np.arange(self.n_bins) if idx is None else idx)
        if outer is not None:
            pos, weights = outer
            full = np.zeros(lead + (pos.size, N_FEATURES), np.float32)
            keep = np.searchsorted(pos, np.arange(self.n_bins) if idx is None else idx)
            full[..., keep, :] = f
            f, n = full, pos.size
        elif idx is not None and idx.size > GATHER_MAX_BINS:
            # Copying the weights of many bins costs more than running the whole bank on
            # contiguous weights: place the features at their bins (zeros elsewhere) and keep
            # the subset's outputs.
            full = np.zeros(lead + (self.n_bins, N_FEATURES), np.float32)
            full[..., idx, :] = f
            f, n, keep = full, self.n_bins, idx
        elif idx is not None:
            sel = torch.from_numpy(idx.astype(np.int64))
            weights = tuple(w.index_select(0, sel) for w in weights)
        x = torch.from_numpy(np.ascontiguousarray(f.reshape(-1, n, N_FEATURES).transpose(1, 0, 2)))
        with torch.inference_mode():
            out = ssdenet_forward(x, *weights)  # (n, N, D)
        maps = out.transpose(0, 1).reshape(lead + (n, self.n_directions)).numpy()
        return maps if keep is None else maps[..., keep, :]

    def _within(self, within, idx: np.ndarray):
        """(sorted positions, gathered weights) of ``within`` from the cache, or None when the
        set is too large to keep (the caller falls back to the other paths)."""
        pos = np.unique(np.asarray(within))
        if pos.ndim != 1 or not np.issubdtype(pos.dtype, np.integer) or (pos.size and (
                pos.min() < 0 or pos.max() >= self.n_bins)):
            raise ConfigError(f"within must be 1-D positions within 0..{self.n_bins - 1}, got {within!r}")
        if not np.isin(idx, pos).all():
            raise ConfigError(f"within ({pos.tolist()}) must contain every position of the subset ({idx.tolist()})")
        if pos.size > WITHIN_MAX_BINS:
            return None
        weights = self._weights()
        # A tensor's version counter changes when training updates it in place, its storage
        # when it is replaced.
        key = (pos.tobytes(), tuple((w.data_ptr(), w._version) for w in weights))
        hit = self._gathered.get(key)
        if hit is None:
            sel = torch.from_numpy(pos.astype(np.int64))
            with torch.no_grad():
                hit = tuple(w.detach().index_select(0, sel) for w in weights)
            self._gathered[key] = hit
            while len(self._gathered) > WITHIN_CACHE:
                self._gathered.popitem(last=False)
        else:
            self._gathered.move_to_end(key)
        return pos, hit

    def frame_maps(self, spectra, valid=None, fusion: str = DEFAULT_FUSION) -> tuple[np.ndarray, np.ndarray]:
        """P(d) of each frame: the existence maps of the frame's valid bank bins, fused.

        Parameters
        ----------
        spectra : array_like, complex (2, 1025) or (K, 2, 1025)
            Front-end spectra (left, right) of one frame or K frames.
        valid : array_like, optional
            Which of the 1025 bins are valid (:func:`valid_bins`): a bool mask (1025,) for all
            frames or (K, 1025) per frame, or integer bin indices; default all. Only the
            bank's own bins are used.
        fusion : str
            How a frame's bins are fused (:data:`FUSIONS`; default :data:`DEFAULT_FUSION`).

        Returns
        -------
        maps : numpy.ndarray, float32 (K, D)
            Zero for a frame without a valid bank bin.
        n_valid : numpy.ndarray, int64 (K,)
            Valid bank bins per frame.
        """
        check_fusion(fusion)
        x = _check_spectra(spectra)
        if x.ndim == 2:
            x = x[None]
        if x.ndim != 3 or x.shape[-1] != N_BINS:
            raise ConfigError(f"spectra must have shape (2, {N_BINS}) or (K, 2, {N_BINS}), got {x.shape}")
        k = x.shape[0]
        if valid is None:
            mask = np.ones((k, self.n_bins), bool)
        else:
            full = _bin_mask(valid, N_BINS, "valid")
            if full.ndim == 1:
                full = np.broadcast_to(full, (k, N_BINS))
            elif full.shape != (k, N_BINS):
                raise ConfigError(f"valid mask must have shape ({N_BINS},) or ({k}, {N_BINS}), got {full.shape}")
            mask = full[:, self.bins]
        n_valid = mask.sum(axis=1).astype(np.int64)
        frames = np.flatnonzero(n_valid)
        maps = np.zeros((k, self.n_directions), np.float32)
        if frames.size == 0:
            return maps, n_valid
        # All bank bins of the frames that have a valid one: gathering the weights of just
        # the valid bins copies them (25 MB for half the paper bank) and costs more than
        # evaluating every bin (measured 5.1 ms against 1.8 ms per frame).
        sel = x[frames][:, :, self.bins]  # (K', 2, n_bins)
        feats = ild_ipd(sel[:, 0], sel[:, 1])  # (K', n_bins, 5)
        inp = torch.from_numpy(np.ascontiguousarray(feats.transpose(1, 0, 2)))
        with torch.inference_mode():
            out = ssdenet_forward(inp, *self._weights()).numpy()  # (n_bins, K', D)
        maps[frames] = fuse(out.transpose(1, 0, 2), mask[frames][:, None, :], fusion)[:, 0]
        return maps, n_valid

    def estimate(self, spectra, valid=None, fusion: str = DEFAULT_FUSION) -> DirectionEstimate | None:
        """The paper's direction estimate from one frame or a whole recording.

        Parameters
        ----------
        spectra : array_like, complex (2, 1025) or (K, 2, 1025)
            Front-end spectra; with K frames the maps of all frames are summed (a whole
            recording gives one estimate).
        valid : array_like, optional
            Valid bins as for :meth:`frame_maps` (default: all bank bins).
        fusion : str
            How each frame's bins are fused (:data:`FUSIONS`); frames are summed.

        Returns
        -------
        DirectionEstimate or None
            ``(P(d) (D,), unit vector (3,), (azimuth_deg, elevation_deg))``; None when no
            bank bin is valid in any frame (nothing to estimate from, e.g. silence).
        """
        maps, n_valid = self.frame_maps(spectra, valid, fusion)
        if n_valid.sum() == 0:
            return None
        p = maps.sum(axis=0)
        k = int(np.argmax(p))
        return DirectionEstimate(p, self.grid.vectors[k].copy(),
                                 (float(self.grid.azimuth_deg[k]), float(self.grid.elevation_deg[k])))

    # -- checkpoints ------------------------------------------------------------------------

    def metadata(self) -> dict:
        """The checkpoint metadata of this bank (JSON-ready)."""
        prof = self.profile
        return {
            "kind": KIND, "version": VERSION, "profile": prof.name if prof else "custom",
            "profile_config": prof.to_dict() if prof else None, "seed": self.seed,
            "hrtf": self.hrtf_ident, "hrtf_name": self.hrtf_name,
            "grid": self.grid.ident, "grid_name": self.grid.name, "n_directions": self.n_directions,
            "bins": self.bins.tolist(), "hidden": self.hidden, "sample_rate": SAMPLE_RATE, "n_fft": N_FFT,
        }

    def save(self, path) -> Path:
        """Write the bank as a checkpoint (atomically); returns the path."""
        return ckpt.save_checkpoint(path, self.state_dict(), self.metadata())

    @classmethod
    def load(cls, path, hrtf, grid: DirectionGrid) -> SSDENetBank:
        """Load a bank and check that it was trained for this HRTF and grid.

        Parameters
        ----------
        path : path-like
            Checkpoint written by :meth:`save`.
        hrtf : HRTF
            The ears it will be used with.
        grid : DirectionGrid
            The output grid it will be used with.

        Raises
        ------
        ConfigError
            Unreadable file, not an SSDENet checkpoint, or trained for another HRTF or grid
            (the message names both idents).
        """
        expected = {"kind": KIND, "hrtf": hrtf.ident, "hrtf_name": hrtf.name, "grid": grid.ident,
                    "grid_name": grid.name}
        state, meta = ckpt.load_checkpoint(path, expected=expected)
        prof = None
        if isinstance(meta.get("profile_config"), dict):
            try:
                cfg = dict(meta["profile_config"])
                cfg["bins"] = tuple(cfg["bins"])
                cfg["snr_db"] = tuple(cfg["snr_db"])
                prof = SSDENetProfile(**cfg)
            except (TypeError, KeyError, ConfigError) as exc:
                raise ConfigError(f"checkpoint {path} has a malformed profile: {exc}") from None
        try:
            bank = cls(grid, meta["bins"], int(meta["hidden"]), hrtf_ident=hrtf.ident, hrtf_name=hrtf.name,
                       profile=prof, seed=meta.get("seed"))
            bank.load_state_dict(state)
        except (KeyError, RuntimeError, TypeError) as exc:
            raise ConfigError(f"checkpoint {path} does not fit an SSDENet bank: {exc}") from None
        bank.eval()
        return bank

    @staticmethod
    def cache_path(hrtf, grid: DirectionGrid, profile) -> Path:
        """Where :meth:`load_or_train` keeps the bank of (HRTF, grid, profile)."""
        return ckpt.cache_path(KIND, get_profile(profile).name, hrtf.ident, grid.ident)

    @classmethod
    def rebuild(cls, hrtf, grid: DirectionGrid, profile, *, seed: int | None = None, progress: bool = True,
                path=None) -> SSDENetBank:
        """Train a bank from scratch and save it (``acoustic-sim train ssdenet``).

        (Not called ``train``: that name is ``torch.nn.Module.train(mode)``.)

        Parameters
        ----------
        hrtf : HRTF
        grid : DirectionGrid
        profile : SSDENetProfile or str
        seed : int, optional
            Default: the profile's seed. Same seed, same weights, bit for bit (on the same
            machine and torch thread count).
        progress : bool
            Show a tqdm progress bar on stderr.
        path : path-like, optional
            Where to save; default :meth:`cache_path`. ``False`` saves nothing.
        """
        from acoustic_sim.auditory.ssdenet_training import train_bank  # imports this module

        bank = train_bank(hrtf, grid, profile, seed=seed, progress=progress)
        if path is not False:
            bank.save(cls.cache_path(hrtf, grid, profile) if path is None else path)
        return bank

    @classmethod
    def load_or_train(cls, hrtf, grid: DirectionGrid, profile, *, progress: bool = True) -> SSDENetBank:
        """The cached bank of (HRTF, grid, profile); trained and cached on first use.

        A cached file of another recipe version, profile definition or seed is retrained
        (and overwritten); an unreadable one is an error that says how to rebuild it.
        """
        prof = get_profile(profile)
        path = cls.cache_path(hrtf, grid, prof)
        if path.is_file():
            try:
                meta = ckpt.read_metadata(path)
            except ConfigError as exc:
                raise ConfigError(f"{exc}; delete it or rebuild it with `acoustic-sim train ssdenet "
                                  f"--hrtf {hrtf.name} --profile {prof.name}`") from None
            if (meta.get("version") == VERSION and meta.get("profile_config") == prof.to_dict()
                    and meta.get("seed") == prof.seed):
                return cls.load(path, hrtf, grid)
        return cls.rebuild(hrtf, grid, prof, progress=progress, path=path)


_TRAINING_NAMES = ("train_bank", "train_command", "training_set", "target_table", "source_directions",
                   "normalized_transfer")


def __getattr__(name: str):
    """The training functions, re-exported lazily from :mod:`.ssdenet_training` (which imports
    this module, so it cannot be imported at the top)."""
    if name in _TRAINING_NAMES:
        from acoustic_sim.auditory import ssdenet_training

        return getattr(ssdenet_training, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
