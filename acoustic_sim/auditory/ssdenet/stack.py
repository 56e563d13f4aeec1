"""The stacked SSDENets of a set of bins over one direction grid, and their evaluation.

:class:`SSDENetStack` holds the stacked weights (:mod:`~acoustic_sim.auditory.ssdenet.networks`)
and evaluates them on ILD/IPD features (:meth:`~SSDENetStack.existence`, running only a
subset of the networks where that is cheaper) or on whole spectra
(:meth:`~SSDENetStack.frame_maps`: each frame's valid bins fused,
:mod:`~acoustic_sim.auditory.ssdenet.fusion`), and gives the paper's estimate
d^ = argmax_k P(d_k) (:class:`SSDENetEstimate`). The trained bank,
:class:`~acoustic_sim.auditory.ssdenet.bank.SSDENetBank`, adds what it was trained for and
its checkpoints.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from acoustic_sim.auditory.features import ild_ipd
from acoustic_sim.auditory.frontend import N_BINS, bin_frequencies
from acoustic_sim.auditory.ssdenet.fusion import DEFAULT_FUSION, check_fusion, fuse
from acoustic_sim.auditory.ssdenet.networks import PARAMETER_NAMES, init_weights, ssdenet_forward, weight_shapes
from acoustic_sim.auditory.ssdenet.recipes import N_FEATURES
from acoustic_sim.auditory.ssdenet.validity import bin_mask, check_spectra
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError

GATHER_MAX_BINS = 4
"""Largest subset of bins whose weights :meth:`SSDENetStack.existence` gathers; a larger one
runs the whole bank (contiguous weights, memory-bound). Measured with the paper bank (32
bins, H = 500, 2 threads): gathering 6 bins and running them 1.48 ms, 16 bins 3.36 ms, the
whole bank 1.34 ms; 2 bins 0.68 ms."""

WITHIN_MAX_BINS = 16
"""Largest set of bins whose gathered weights :meth:`SSDENetStack.existence` keeps for reuse
(``within=``: a detected class's characteristic bins); larger sets are not cached."""

WITHIN_CACHE = 8
"""Gathered weight sets kept (least recently used dropped): at most 8 x 16 x 1.7 MB for
the paper bank."""


class SSDENetEstimate(NamedTuple):
    """The bank's own estimate (:meth:`SSDENetStack.estimate`): the fused map and its argmax.

    Unpacks as ``(existence, vector, (azimuth_deg, elevation_deg))``. The pipeline's
    per-sound result is :class:`acoustic_sim.auditory.percept.DirectionEstimate`, which adds
    a confidence, the number of bins and the method.

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


class SSDENetStack(nn.Module):
    """SSDENets for a set of frequency bins over one direction grid: the weights and their evaluation.

    Parameters
    ----------
    grid : DirectionGrid
        The D output directions.
    bins : sequence of int
        The rFFT bins (2048-point front end) that have a network, increasing.
    hidden : int
        Hidden units H per layer.
    generator : torch.Generator, optional
        Draws the initial weights (default: a generator seeded with 0).
    output_prior : float
        Initial value of the outputs (:func:`init_weights`), in (0, 1).
    weights : dict of str to torch.Tensor, optional
        Trained weights to start from instead (named and shaped as :func:`init_weights`
        returns them); ``generator`` and ``output_prior`` are then unused.
    """

    def __init__(self, grid: DirectionGrid, bins, hidden: int, *, generator: torch.Generator | None = None,
                 output_prior: float = 0.5, weights: dict[str, torch.Tensor] | None = None) -> None:
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
        if weights is None:
            gen = generator if generator is not None else torch.Generator().manual_seed(0)
            weights = init_weights(bins.size, self.hidden, len(grid), gen, output_prior=output_prior)
        else:
            shapes = weight_shapes(bins.size, self.hidden, len(grid))
            got = {name: tuple(t.shape) for name, t in weights.items()}
            if got != shapes:
                raise ConfigError(f"weights must have the shapes {shapes}, got {got}")
        for name in PARAMETER_NAMES:
            setattr(self, name, nn.Parameter(weights[name]))
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
        x = check_spectra(spectra)
        if x.ndim == 2:
            x = x[None]
        if x.ndim != 3 or x.shape[-1] != N_BINS:
            raise ConfigError(f"spectra must have shape (2, {N_BINS}) or (K, 2, {N_BINS}), got {x.shape}")
        k = x.shape[0]
        if valid is None:
            mask = np.ones((k, self.n_bins), bool)
        else:
            full = bin_mask(valid, N_BINS, "valid")
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

    def estimate(self, spectra, valid=None, fusion: str = DEFAULT_FUSION) -> SSDENetEstimate | None:
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
        SSDENetEstimate or None
            ``(P(d) (D,), unit vector (3,), (azimuth_deg, elevation_deg))``; None when no
            bank bin is valid in any frame (nothing to estimate from, e.g. silence).
        """
        maps, n_valid = self.frame_maps(spectra, valid, fusion)
        if n_valid.sum() == 0:
            return None
        p = maps.sum(axis=0)
        k = int(np.argmax(p))
        return SSDENetEstimate(p, self.grid.vectors[k].copy(),
                                 (float(self.grid.azimuth_deg[k]), float(self.grid.elevation_deg[k])))
