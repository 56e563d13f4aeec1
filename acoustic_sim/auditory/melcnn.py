"""MelCNN: the paper's binaural environmental sound detector.

Section "Binaural Environmental Sound Detection" of Omura et al. 2022: a logMel-CNN
(Piczak 2015) per ear on the normalised 25 x 128 log-mel patch, a sigmoid existence
probability per class, the two ears fused by their volumes, and per class the
characteristic frequency bins that select the bins SSDENet sums over.

Network (Piczak's structure, resized for a 2 ms budget)
-------------------------------------------------------
Piczak's logMel-CNN is conv (80 filters, 57 x 6 freq x time) - max-pool (4 x 3, stride
1 x 3) - conv (80, 1 x 3) - max-pool (1 x 3) - two fully connected layers of 5000 ReLUs -
output, dropout 0.5. On our 128 x 25 input that network has 80 M parameters (the two
5000-unit layers are over 100 MB of weights to stream per frame), far over the budget of
2 ms for both ears (``torch.set_num_threads(2)``, the ears as one batch of 2), so the layers
keep Piczak's order and kernel shapes but shrink (profile ``paper``; input freq x time 128
x 25):

=======  =============================================  ============  =====================
layer    paper profile                                  output        why
=======  =============================================  ============  =====================
conv1    48 filters 21 x 5, stride 2 x 1, ReLU          48 x 54 x 21  tall filters as in
                                                                      Piczak (21 bands ~
                                                                      1.5 octaves); stride
                                                                      2 in frequency
                                                                      halves the cost
pool1    max 4 x 3, stride 2 x 3; dropout 0.2           48 x 26 x 7   Piczak's 4 x 3
conv2    48 filters 1 x 3, ReLU                         48 x 26 x 5   Piczak's 1 x 3
pool2    max 1 x 3, stride 1 x 3; dropout 0.2           48 x 26 x 2   Piczak's 1 x 3
fc1/fc2  384 ReLUs each, dropout 0.2                    384           Piczak's two hidden
                                                                      layers
out      6 sigmoids                                     6
=======  =============================================  ============  =====================

Pools run in ceil mode: in floor mode the time axis (25 -> 21 -> 7 -> 5 -> 1) would keep
only frames 0-18 and never see the newest 6 frames (96 ms), where onsets are. Dropout is
0.2, not Piczak's 0.5: this small network underfits, and less dropout with more epochs
helped.

1.12 M parameters, about 1 ms per frame of both ears: 48 / 384 is the largest size that
leaves about half the budget for a loaded machine (:func:`frame_time_ms` measures it again;
``train_command`` reports it).

Loss: the paper's KL divergence, in the form that fits independent sigmoid outputs
----------------------------------------------------------------------------------
Each output is the existence probability of one class, independent of the others (sounds
co-occur), so the model's prediction for class c is the Bernoulli distribution
``(p_c, 1 - p_c)`` and the target is ``(y_c, 1 - y_c)``. The loss is the sum over classes
of the Bernoulli KL divergence, averaged over the batch::

    L = mean_batch sum_c [ y_c log(y_c / p_c) + (1 - y_c) log((1 - y_c) / (1 - p_c)) ]
      = BCE(p, y) - H(y)

(:func:`kl_divergence_loss`). A KL between label and output distributions normalised over
the classes would make the classes compete (softmax-like: two co-occurring sounds could
not both be near 1) and has no target for "nothing audible". With hard labels the form
above equals binary cross-entropy; with the soft targets of windows where a sound is only
partly audible (:mod:`~acoustic_sim.auditory.sound_data`) its minimum is 0 at p = y.
Optimiser: Adam (the paper), cosine-decayed learning rate.

Binaural fusion
---------------
:func:`fuse`: ``p = (V_l p_l + V_r p_r) / (V_l + V_r)`` with V the ear volumes
(:func:`~acoustic_sim.auditory.features.ear_volume`, mean over the patch's frames); when
both ears are silent (``V_l + V_r = 0``) it is the plain mean of the two ears.

Characteristic bins
-------------------
Per class, from the training data: the mean over the frames where the class was audible
(:mod:`~acoustic_sim.auditory.sound_data`) of its own unit-sum power spectrum at the ear,
then the smallest set of FFT bins holding ``energy_fraction`` (90 %) of that mean energy
(:func:`characteristic_bins`). The sets are stored in the checkpoint metadata and handed to
SSDENet as ``MelCNN.characteristic_bins: dict[str, numpy.ndarray]`` (int64 indices into
the 1025 bins, ascending).

Profiles, caching, randomness
-----------------------------
``paper``: the detector above, 40 000 training windows (about 2 860 scenes, 64 BRIRs),
14 epochs of one random ear per window, batch 128, Adam 2e-3 cosine-decayed to 1e-4.
``fast``: 16 filters, 128 units, 1 200 windows (4 BRIRs), 30 epochs; for tests only.

Measurements (the sizes, dropout and recipes compared: frame times, training times,
held-out F1): docs/notes/melcnn_recipes.md.

Trained on first use and cached as a checkpoint
(:mod:`~acoustic_sim.auditory.checkpoint`) in the cache folder (file
``melcnn-<profile>-v<VERSION>-<recipe ident>.pt``, :attr:`Profile.ident`); ``acoustic-sim train melcnn`` rebuilds it
(:func:`train_command`). Training data come from ``SeedSequence(profile.seed).spawn(3)[0]``; held-out validation uses stream 1
(:func:`heldout_rng`), with BRIRs at other positions and other sound instances, and the
reported evaluation (``eval paper``) stream 2 (:func:`report_rng`), which no choice looked at. Torch's
global RNG (weight init, dropout) is seeded inside :func:`torch.random.fork_rng`, so
training is deterministic and leaves the caller's torch state alone.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
import warnings
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from acoustic_sim.acoustics import sounds
from acoustic_sim.auditory import checkpoint
from acoustic_sim.auditory import features as feat
from acoustic_sim.auditory.frontend import N_BINS
from acoustic_sim.auditory.sound_data import CLASSES, SoundDataConfig, SoundExamples, generate_examples
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

KIND = "melcnn"
"""Checkpoint ``kind``."""

VERSION = 2
"""Recipe version: bump when the data, the network or the training change (old caches are
then ignored, as the version is part of the cache file name)."""


# --------------------------------------------------------------------------- configuration


@dataclasses.dataclass(frozen=True, kw_only=True)
class NetConfig:
    """Layer sizes of the logMel-CNN (input: 1 x 128 mel x 25 frames per ear).

    Parameters
    ----------
    conv1_channels : int
        Filters of the first convolution.
    conv1_kernel : tuple of int
        (frequency bands, frames) of the first filters.
    conv1_stride : tuple of int
        (frequency, time) stride of the first convolution.
    pool1 : tuple of int
        Max-pool window (frequency, time) after conv1.
    pool1_stride : tuple of int
        Max-pool stride (frequency, time) after conv1.
    conv2_channels : int
        Filters of the second convolution.
    conv2_kernel : tuple of int
        (frequency, time) of the second filters.
    pool2 : tuple of int
        Max-pool window and stride (frequency, time) after conv2.
    hidden : int
        Units of each of the two fully connected hidden layers.
    dropout : float
        Dropout probability after each pooling and hidden layer, 0 <= p < 1.
    """

    conv1_channels: int = 48
    conv1_kernel: tuple[int, int] = (21, 5)
    conv1_stride: tuple[int, int] = (2, 1)
    pool1: tuple[int, int] = (4, 3)
    pool1_stride: tuple[int, int] = (2, 3)
    conv2_channels: int = 48
    conv2_kernel: tuple[int, int] = (1, 3)
    pool2: tuple[int, int] = (1, 3)
    hidden: int = 384
    dropout: float = 0.5

    def __post_init__(self) -> None:
        for name in ("conv1_channels", "conv2_channels", "hidden"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 10000:
                raise ConfigError(f"NetConfig.{name} must be an integer 1..10000, got {v!r}")
        for name in ("conv1_kernel", "conv1_stride", "pool1", "pool1_stride", "conv2_kernel", "pool2"):
            v = getattr(self, name)
            if len(v) != 2 or any(isinstance(x, bool) or not isinstance(x, int) or x < 1 for x in v):
                raise ConfigError(f"NetConfig.{name} must be two positive integers (frequency, time), got {v!r}")
        if not 0.0 <= self.dropout < 1.0:
            raise ConfigError(f"NetConfig.dropout must be in [0, 1), got {self.dropout}")
        if min(self.feature_shape()) < 1:
            raise ConfigError(f"NetConfig {self} leaves no features of a {feat.N_MELS} x {feat.MEL_FRAMES} input")

    def feature_shape(self) -> tuple[int, int, int]:
        """(channels, frequency, time) entering the first fully connected layer."""
        f, t = feat.N_MELS, feat.MEL_FRAMES
        f = (f - self.conv1_kernel[0]) // self.conv1_stride[0] + 1
        t = (t - self.conv1_kernel[1]) // self.conv1_stride[1] + 1
        f, t = _pooled(f, self.pool1[0], self.pool1_stride[0]), _pooled(t, self.pool1[1], self.pool1_stride[1])
        f, t = f - self.conv2_kernel[0] + 1, t - self.conv2_kernel[1] + 1
        f, t = _pooled(f, self.pool2[0], self.pool2[0]), _pooled(t, self.pool2[1], self.pool2[1])
        return self.conv2_channels, f, t


def _pooled(n: int, window: int, stride: int) -> int:
    """Output length of a max-pool in ceil mode (the last, partial window is kept)."""
    if n < window:
        return 0
    out = -(-(n - window) // stride) + 1
    return out - 1 if (out - 1) * stride >= n else out


@dataclasses.dataclass(frozen=True, kw_only=True)
class Profile:
    """A trained-model recipe: network, data and optimisation.

    Parameters
    ----------
    name : str
        ``paper`` or ``fast``.
    net : NetConfig
    data : SoundDataConfig
    n_examples : int
        Training windows (each gives two ear examples).
    brirs_per_room : int
        BRIRs rendered per room for the training bank.
    epochs : int
        Passes over the training windows.
    batch_size : int
        Windows per Adam step (one randomly chosen ear of each, drawn anew every epoch).
    learning_rate : float
        Initial Adam step size, cosine-decayed to 5 % over the run.
    energy_fraction : float
        Share of a class's mean energy its characteristic bins hold (0-1).
    seed : int
        Root of the training (stream 0) and held-out (stream 1) seed sequences.
    eval_examples : int
        Held-out windows for :func:`evaluate` by default (``eval paper``).
    """

    name: str
    net: NetConfig
    data: SoundDataConfig = dataclasses.field(default_factory=SoundDataConfig)
    n_examples: int
    brirs_per_room: int
    epochs: int
    batch_size: int = 128
    learning_rate: float = 1e-3
    energy_fraction: float = 0.9
    seed: int = 2022
    eval_examples: int = 2000

    def __post_init__(self) -> None:
        for name in ("n_examples", "brirs_per_room", "epochs", "batch_size", "eval_examples"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ConfigError(f"Profile.{name} must be a positive integer, got {v!r}")
        if not 0 < self.learning_rate < 1:
            raise ConfigError(f"Profile.learning_rate must be in (0, 1), got {self.learning_rate}")
        if not 0 < self.energy_fraction <= 1:
            raise ConfigError(f"Profile.energy_fraction must be in (0, 1], got {self.energy_fraction}")

    @property
    def ident(self) -> str:
        """16 hex digits of the recipe (network, data, optimisation, seed; not the name or the
        evaluation size): part of the cache file's name, so that a model cached by an older
        recipe of the same profile is not loaded for the new one."""
        recipe = {k: v for k, v in dataclasses.asdict(self).items() if k not in ("name", "eval_examples")}
        return hashlib.sha256(json.dumps(recipe, sort_keys=True, default=str).encode()).hexdigest()[:16]


PROFILES: dict[str, Profile] = {
    "paper": Profile(name="paper", net=NetConfig(dropout=0.2), n_examples=40000, brirs_per_room=16, epochs=14,
                     learning_rate=2e-3),
    "fast": Profile(
        name="fast",
        net=NetConfig(conv1_channels=16, conv2_channels=16, hidden=128, dropout=0.1),
        n_examples=1200, brirs_per_room=1, epochs=30, batch_size=32, learning_rate=3e-3, eval_examples=300,
    ),
}
"""The recipes by name."""


def get_profile(profile: str | Profile) -> Profile:
    """A :class:`Profile` by name (``paper``, ``fast``), or the profile itself."""
    if isinstance(profile, Profile):
        return profile
    if profile not in PROFILES:
        raise ConfigError(f"unknown MelCNN profile {profile!r}; valid: {', '.join(PROFILES)}")
    return PROFILES[profile]


def _stream(profile: str | Profile, k: int) -> np.random.Generator:
    """Stream ``k`` of the three that a profile's seed spawns (training, validation, report)."""
    return np.random.default_rng(np.random.SeedSequence(get_profile(profile).seed).spawn(3)[k])


def training_rng(profile: str | Profile) -> np.random.Generator:
    """The generator of a profile's training data (stream 0 of its seed)."""
    return _stream(profile, 0)


def heldout_rng(profile: str | Profile = "paper") -> np.random.Generator:
    """A generator for held-out validation data (stream 1 of its seed), independent of the
    training stream: the recipes' measurements above, and the tests, use it."""
    return _stream(profile, 1)


def report_rng(profile: str | Profile = "paper") -> np.random.Generator:
    """A generator for the reported evaluation (``eval paper``'s ``detection.json``): stream 2
    of the profile's seed, which neither training nor any choice of recipe looked at (those
    compared F1 on :func:`heldout_rng`'s windows, so an F1 there is the chosen recipe's best
    draw, not an estimate)."""
    return _stream(profile, 2)


# --------------------------------------------------------------------------- functional core


def kl_divergence_loss(logits: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """Sum over classes of KL(Bernoulli(y) || Bernoulli(sigmoid(logits))), batch mean.

    Parameters
    ----------
    logits : torch.Tensor
        (N, C) pre-sigmoid outputs.
    targets : torch.Tensor
        (N, C) target probabilities in [0, 1].

    Returns
    -------
    torch.Tensor
        Scalar, >= 0 (nats); 0 when ``sigmoid(logits) == targets``.
    """
    if logits.shape != targets.shape:
        raise ConfigError(f"logits {tuple(logits.shape)} and targets {tuple(targets.shape)} differ in shape")
    bce = F.binary_cross_entropy_with_logits(logits, targets, reduction="none")
    entropy = -(torch.special.xlogy(targets, targets) + torch.special.xlogy(1 - targets, 1 - targets))
    return (bce - entropy).sum(dim=-1).mean()


def fuse(p_left, p_right, v_left, v_right) -> np.ndarray:
    """The paper's volume-weighted fusion of the two ears' probabilities.

    ``p = (V_l p_l + V_r p_r) / (V_l + V_r)``; where ``V_l + V_r == 0`` (both ears silent)
    the result is the plain mean ``(p_l + p_r) / 2``.

    Parameters
    ----------
    p_left, p_right : array_like
        (..., C) per-ear class probabilities in [0, 1].
    v_left, v_right : array_like
        (...) ear volumes (any non-negative loudness measure, e.g. mean power).

    Returns
    -------
    numpy.ndarray
        float64 (..., C) fused probabilities.

    Raises
    ------
    ConfigError
        Mismatched shapes, probabilities outside [0, 1], or negative / non-finite volumes.
    """
    pl, pr = np.asarray(p_left, np.float64), np.asarray(p_right, np.float64)
    vl, vr = np.asarray(v_left, np.float64), np.asarray(v_right, np.float64)
    if pl.shape != pr.shape or pl.ndim < 1:
        raise ConfigError(f"left and right probabilities must have the same shape (..., C), got {pl.shape} and {pr.shape}")
    if vl.shape != vr.shape or vl.shape != pl.shape[:-1]:
        raise ConfigError(f"volumes must have shape {pl.shape[:-1]} (the probabilities' without the class axis), "
                          f"got {vl.shape} and {vr.shape}")
    for p in (pl, pr):
        if not np.all((p >= 0) & (p <= 1)):
            raise ConfigError("probabilities must lie in [0, 1] (NaN is not allowed)")
    for v in (vl, vr):
        if not np.all(np.isfinite(v) & (v >= 0)):
            raise ConfigError("ear volumes must be finite and >= 0")
    return fuse_unchecked(pl, pr, vl, vr)


def fuse_unchecked(pl: np.ndarray, pr: np.ndarray, vl, vr) -> np.ndarray:
    """:func:`fuse` without its argument checks, for callers whose inputs are valid by
    construction (the streaming pipeline, once per frame): float64 arrays ``pl``, ``pr``
    (..., C) and volumes ``vl``, ``vr`` (...) or floats."""
    vl, vr = np.asarray(vl, np.float64), np.asarray(vr, np.float64)
    total = (vl + vr)[..., None]
    if total.ndim == 1:  # one frame: plain arithmetic, the same operations as the array form
        t = float(total[0])
        return 0.5 * (pl + pr) if t == 0 else (vl[..., None] * pl + vr[..., None] * pr) / t
    silent = total == 0
    safe = np.where(silent, 1.0, total)
    weighted = (vl[..., None] * pl + vr[..., None] * pr) / safe
    return np.where(silent, 0.5 * (pl + pr), weighted)


def patch_volumes(spectra) -> np.ndarray:
    """Ear volumes of a patch for :func:`fuse`: mean ear volume over its frames.

    spectra (..., T, 2, n_bins) complex -> float64 (..., 2).
    """
    x = np.asarray(spectra)
    if x.ndim < 3 or x.shape[-2] != 2:
        raise ConfigError(f"spectra must have shape (..., T, 2, n_bins), got {x.shape}")
    return feat.ear_volume(x).mean(axis=-2)


def characteristic_bins(spectrum_sum, spectrum_frames, *, energy_fraction: float = 0.9,
                        classes=CLASSES) -> dict[str, np.ndarray]:
    """The smallest set of FFT bins holding ``energy_fraction`` of each class's mean energy.

    Parameters
    ----------
    spectrum_sum : array_like
        (C, n_bins): per class, the sum of unit-sum power spectra over audible frames
        (:attr:`SoundExamples.spectrum_sum`).
    spectrum_frames : array_like
        (C,): the number of those frames.
    energy_fraction : float
        In (0, 1].
    classes : sequence of str
        Names of the C classes.

    Returns
    -------
    dict of str to numpy.ndarray
        Per class, int64 bin indices, ascending (bin i is at i * 44100 / 2048 Hz).

    Raises
    ------
    ConfigError
        A class with no audible frame (the data set is too small to characterise it).
    """
    s = np.asarray(spectrum_sum, np.float64)
    n = np.asarray(spectrum_frames)
    if s.ndim != 2 or s.shape[0] != len(classes) or n.shape != (len(classes),):
        raise ConfigError(f"spectrum_sum must be ({len(classes)}, n_bins) and spectrum_frames ({len(classes)},), "
                          f"got {s.shape} and {n.shape}")
    if not 0 < energy_fraction <= 1:
        raise ConfigError(f"energy_fraction must be in (0, 1], got {energy_fraction}")
    out = {}
    for c, name in enumerate(classes):
        if n[c] <= 0 or not np.any(s[c] > 0):
            raise ConfigError(f"class {name!r} is never audible in the data: cannot find its characteristic bins "
                              "(use more examples)")
        mean = s[c] / n[c]
        order = np.argsort(-mean, kind="stable")
        cum = np.cumsum(mean[order]) / mean.sum()
        k = int(np.searchsorted(cum, energy_fraction - 1e-12) + 1)
        out[name] = np.sort(order[:k]).astype(np.int64)
    return out


# --------------------------------------------------------------------------- the network


def _pool(pool: nn.MaxPool2d, x: torch.Tensor) -> torch.Tensor:
    """``pool(x)`` computed in channels-last memory, returned contiguous (NCHW).

    Torch's CPU max-pool is slow on NCHW tensors (one frame of both ears, one thread:
    ``paper`` pool1 0.9 ms of a 1.7 ms forward pass) and fast on channels-last ones
    (0.06 ms); a maximum does not depend on memory layout, so the result is the same bit
    for bit, and the convolutions keep their NCHW layout (and their exact outputs).
    Measured forward pass, batch of 2 ears, one thread: ``paper`` 1.71 -> 0.99 ms,
    ``fast`` 0.81 -> 0.41 ms.
    """
    return pool(x.contiguous(memory_format=torch.channels_last)).contiguous()


class MelCNN(nn.Module):
    """The logMel-CNN detector of one ear, with the metadata it was trained with.

    Parameters
    ----------
    net : NetConfig
        Layer sizes.
    classes : tuple of str
        Output classes (default the six sound classes).
    characteristic_bins : dict of str to numpy.ndarray, optional
        Per class, the FFT bins of its energy (filled in by training or loading).
    metadata : dict, optional
        Checkpoint metadata (profile, training provenance).

    Attributes
    ----------
    characteristic_bins : dict of str to numpy.ndarray
        int64 indices into the 1025 bins, per class.
    """

    def __init__(self, net: NetConfig | None = None, *, classes=CLASSES, characteristic_bins=None,
                 metadata: dict | None = None) -> None:
        super().__init__()
        self.net_config = NetConfig() if net is None else net
        self.classes = tuple(classes)
        self.characteristic_bins = {k: np.asarray(v, np.int64) for k, v in (characteristic_bins or {}).items()}
        self.metadata = dict(metadata or {})
        c = self.net_config
        self.conv1 = nn.Conv2d(1, c.conv1_channels, c.conv1_kernel, stride=c.conv1_stride)
        # Ceil mode: a floor-mode pool would drop the last partial window, and in time
        # that is the newest frames (25 -> 21 -> 7 -> 5 -> 1 would see frames 0-18 only).
        self.pool1 = nn.MaxPool2d(c.pool1, c.pool1_stride, ceil_mode=True)
        self.conv2 = nn.Conv2d(c.conv1_channels, c.conv2_channels, c.conv2_kernel)
        self.pool2 = nn.MaxPool2d(c.pool2, c.pool2, ceil_mode=True)
        self.fc1 = nn.Linear(int(np.prod(c.feature_shape())), c.hidden)
        self.fc2 = nn.Linear(c.hidden, c.hidden)
        self.out = nn.Linear(c.hidden, len(self.classes))
        self.dropout = nn.Dropout(c.dropout)

    def forward(self, patches: torch.Tensor) -> torch.Tensor:
        """Class logits of log-mel patches.

        Parameters
        ----------
        patches : torch.Tensor
            (N, 25, 128) float32: normalised log-mel patches (frames x mel bands), one ear each.

        Returns
        -------
        torch.Tensor
            (N, C) logits; ``sigmoid`` gives the existence probabilities.
        """
        x = patches.unsqueeze(1).transpose(2, 3).contiguous()  # (N, 1, mel, frames): Piczak's freq x time
        x = self.dropout(_pool(self.pool1, F.relu(self.conv1(x))))
        x = self.dropout(_pool(self.pool2, F.relu(self.conv2(x))))
        x = self.dropout(F.relu(self.fc1(x.flatten(1))))
        x = self.dropout(F.relu(self.fc2(x)))
        return self.out(x)

    # -- inference -------------------------------------------------------------------------
    def predict(self, patches) -> np.ndarray:
        """Per-ear existence probabilities.

        Parameters
        ----------
        patches : array_like
            (2, 25, 128) for one frame (left, right) or (N, 2, 25, 128); values from
            :func:`~acoustic_sim.auditory.features.log_mel_patches` / ``MelHistory.patch()``.

        Returns
        -------
        numpy.ndarray
            float32 (2, C) or (N, 2, C) in [0, 1]. The ears run as one batch.
        """
        x = np.asarray(patches, dtype=np.float32)
        shape = (2, feat.MEL_FRAMES, feat.N_MELS)
        if x.shape[-3:] != shape or x.ndim not in (3, 4):
            raise ConfigError(f"patches must have shape {shape} or (N, *{shape}), got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ConfigError("patches contain NaN or inf")
        lead = x.shape[:-3]
        if self.training:  # Module.eval() walks every submodule: 0.14 ms a frame when called each time
            self.eval()
        with torch.inference_mode():
            p = torch.sigmoid(self(torch.from_numpy(x.reshape(-1, *shape[1:]))))
        return p.numpy().reshape(*lead, 2, len(self.classes))

    def detect(self, patches, volumes) -> np.ndarray:
        """Fused (binaural) existence probabilities, :func:`fuse` of :meth:`predict`.

        Parameters
        ----------
        patches : array_like
            (2, 25, 128) or (N, 2, 25, 128).
        volumes : array_like
            (2,) or (N, 2): V_l, V_r (e.g. :func:`patch_volumes`).

        Returns
        -------
        numpy.ndarray
            float64 (C,) or (N, C).
        """
        p = self.predict(patches)
        v = np.asarray(volumes, np.float64)
        if v.shape != p.shape[:-1]:
            raise ConfigError(f"volumes must have shape {p.shape[:-1]}, got {v.shape}")
        return fuse(p[..., 0, :], p[..., 1, :], v[..., 0], v[..., 1])

    # -- checkpoints -----------------------------------------------------------------------
    def save(self, path) -> Path:
        """Write the weights and metadata (with the characteristic bins) to ``path``."""
        meta = dict(self.metadata)
        meta.update(
            kind=KIND, version=VERSION, classes=list(self.classes), sample_rate=SAMPLE_RATE,
            net=dataclasses.asdict(self.net_config), mel=_mel_signature(),
            characteristic_bins={k: [int(i) for i in v] for k, v in self.characteristic_bins.items()},
        )
        meta.setdefault("profile", "custom")
        return checkpoint.save_checkpoint(path, self.state_dict(), meta)

    @classmethod
    def load(cls, path) -> MelCNN:
        """Read a checkpoint written by :meth:`save`.

        Raises
        ------
        ConfigError
            Missing or unreadable file, another model kind, another sample rate or log-mel
            front end, or an unknown recipe version.
        """
        state, meta = checkpoint.load_checkpoint(
            path, expected={"kind": KIND, "sample_rate": SAMPLE_RATE, "version": VERSION, "mel": _mel_signature()})
        try:
            net = NetConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in meta["net"].items()})
            model = cls(net, classes=tuple(meta["classes"]), metadata=meta,
                        characteristic_bins={k: np.asarray(v, np.int64) for k, v in meta["characteristic_bins"].items()})
            model.load_state_dict(state)
        except (KeyError, TypeError, RuntimeError) as exc:
            raise ConfigError(f"checkpoint {path} does not match the MelCNN layout: {exc}") from None
        for name, bins in model.characteristic_bins.items():
            if bins.size and (bins.min() < 0 or bins.max() >= N_BINS):
                raise ConfigError(f"checkpoint {path}: characteristic bins of {name!r} outside 0..{N_BINS - 1}")
        model.eval()
        return model

    @classmethod
    def cache_path(cls, profile: str) -> Path:
        """Where the cached model of a profile lives (in :func:`checkpoint.cache_dir`)."""
        prof = get_profile(profile)
        return checkpoint.cache_path(KIND, prof.name, f"v{VERSION}", prof.ident)

    @classmethod
    def load_or_train(cls, profile: str = "paper", *, progress: bool = True) -> MelCNN:
        """The cached model of ``profile``, trained (and cached) first if there is none.

        A cached file that cannot be read is an error (rebuild it with
        ``acoustic-sim train melcnn --profile PROFILE``), never silently replaced.
        """
        path = cls.cache_path(profile)
        if path.exists():
            model = cls.load(path)
            trained_on, here = model.metadata.get("voice_engine"), sounds.voice_engine()
            if trained_on is not None and trained_on != here:
                warnings.warn(f"{path.name} was trained on {trained_on} voices and this machine speaks with {here}: "
                              f"rebuild it with `acoustic-sim train melcnn --profile {model.metadata['profile']}`",
                              RuntimeWarning, stacklevel=2)
            return model
        model = train(profile, progress=progress)
        model.save(path)
        return model


def _mel_signature() -> dict:
    """The log-mel front end a model was trained on (a checkpoint must match it)."""
    return {"n_mels": feat.N_MELS, "frames": feat.MEL_FRAMES, "fmin_hz": feat.MEL_FMIN_HZ,
            "fmax_hz": feat.MEL_FMAX_HZ, "range_db": feat.MEL_RANGE_DB}


# --------------------------------------------------------------------------- training


def train(profile: str | Profile = "paper", *, progress: bool = True, examples: SoundExamples | None = None) -> MelCNN:
    """Generate the profile's training data and train a MelCNN on it.

    Parameters
    ----------
    profile : str or Profile
        ``paper``, ``fast`` or a custom :class:`Profile`.
    progress : bool
        Progress bars for data generation and training.
    examples : SoundExamples, optional
        Use these windows instead of generating ``profile.n_examples`` of them.

    Returns
    -------
    MelCNN
        In eval mode, with characteristic bins and metadata (training time, data size,
        final loss).
    """
    from acoustic_sim.progress import progress_bar

    prof = get_profile(profile)
    t0 = time.perf_counter()
    if examples is None:
        examples = generate_examples(prof.n_examples, training_rng(prof), config=prof.data,
                                     brirs_per_room=prof.brirs_per_room, dtype=np.float16, progress=progress)
    bins = characteristic_bins(examples.spectrum_sum, examples.spectrum_frames, energy_fraction=prof.energy_fraction)
    t_data = time.perf_counter() - t0
    # Each ear is one example, but the two ears of a window are nearly the same picture:
    # every epoch takes one randomly chosen ear of every window, which halves the cost of an
    # epoch. float16 storage halves memory; batches are cast to float32.
    x = torch.from_numpy(np.ascontiguousarray(examples.patches))  # (N, 2, T, M)
    y = torch.from_numpy(np.ascontiguousarray(examples.targets, dtype=np.float32))  # (N, 2, C)
    n = x.shape[0]
    steps_per_epoch = math.ceil(n / prof.batch_size)
    total = steps_per_epoch * prof.epochs
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(prof.seed)
        model = MelCNN(prof.net)
        opt = torch.optim.Adam(model.parameters(), lr=prof.learning_rate)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=total, eta_min=0.05 * prof.learning_rate)
        shuffle = torch.Generator().manual_seed(prof.seed)
        model.train()
        bar = progress_bar(total=total, desc=f"MelCNN {prof.name}", disable=not progress, dynamic_ncols=True, leave=False)
        epoch_loss = float("nan")
        for epoch in range(prof.epochs):
            order = torch.randperm(n, generator=shuffle)
            ears = torch.randint(0, 2, (n,), generator=shuffle)
            running, seen = 0.0, 0
            for s in range(steps_per_epoch):
                idx = order[s * prof.batch_size:(s + 1) * prof.batch_size]
                ear = ears[idx]
                loss = kl_divergence_loss(model(x[idx, ear].float()), y[idx, ear])
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                sched.step()
                running += float(loss.detach()) * idx.numel()
                seen += idx.numel()
                bar.update(1)
                if s % 20 == 0:
                    bar.set_postfix(epoch=epoch + 1, loss=f"{running / seen:.4f}")
            epoch_loss = running / seen
        bar.close()
    model.eval()
    model.characteristic_bins = bins
    model.metadata = {
        "profile": prof.name, "seed": prof.seed, "n_examples": len(examples), "epochs": prof.epochs,
        "batch_size": prof.batch_size, "learning_rate": prof.learning_rate, "energy_fraction": prof.energy_fraction,
        "data": _jsonable(dataclasses.asdict(prof.data)), "final_loss": epoch_loss,
        "data_seconds": round(t_data, 2), "train_seconds": round(time.perf_counter() - t0, 2),
        "hrtf_name": "kemar", "hrtf": _kemar_ident(), "voice_engine": sounds.voice_engine(),
    }
    return model


def _jsonable(d: dict) -> dict:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in d.items()}


def _kemar_ident() -> str:
    from acoustic_sim.acoustics.hrtf import HRTF

    return HRTF.load("kemar").ident


def train_command(profile: str = "paper", out=None) -> dict:
    """What ``acoustic-sim train melcnn`` runs: train afresh and write the checkpoint.

    Parameters
    ----------
    profile : str
        ``paper`` or ``fast``.
    out : path-like, optional
        Checkpoint path; default the cache file that :meth:`MelCNN.load_or_train` reads.

    Returns
    -------
    dict
        JSON-ready summary: ``kind``, ``profile``, ``path``, ``train_seconds`` (all of
        it, data generation included), ``data_seconds`` (of which data), ``n_examples``, ``final_loss``, ``characteristic_bins`` (number
        of bins per class) and ``frame_ms`` (both ears, this machine's current threads).
    """
    prof = get_profile(profile)
    model = train(prof, progress=True)
    path = model.save(MelCNN.cache_path(prof.name) if out is None else Path(out))
    m = model.metadata
    return {
        "kind": KIND, "profile": prof.name, "path": str(path), "train_seconds": m["train_seconds"],
        "data_seconds": m["data_seconds"], "n_examples": m["n_examples"], "final_loss": round(m["final_loss"], 5),
        "characteristic_bins": {k: int(v.size) for k, v in model.characteristic_bins.items()},
        "frame_ms": round(frame_time_ms(model), 3),
    }


# --------------------------------------------------------------------------- evaluation


def evaluate(model: MelCNN, rng: np.random.Generator, n_examples: int, *, threshold: float = 0.5,
             brirs_per_room: int = 4, examples: SoundExamples | None = None, progress: bool = False) -> dict:
    """Detection scores on held-out generated windows (the paper's F-score).

    Parameters
    ----------
    model : MelCNN
    rng : numpy.random.Generator
        Held-out stream (e.g. :func:`heldout_rng`): new BRIR positions, sounds and noise.
    n_examples : int
        Windows to generate (mixtures, noise and reverberation as in training).
    threshold : float
        A class is detected when its fused probability is >= threshold.
    brirs_per_room : int
        Size of the held-out BRIR bank.
    examples : SoundExamples, optional
        Score these windows instead of generating new ones.
    progress : bool
        Show progress bars.

    Returns
    -------
    dict
        ``{"f1_macro", "per_class": {class: {"precision", "recall", "f1", "support"}},
        "threshold", "n_examples"}``. Per class, an undefined precision or recall (no
        detections, no positives) counts as 0, and F1 as 1 when the class is neither
        present nor detected anywhere.
    """
    if not 0 < threshold < 1:
        raise ConfigError(f"threshold must be in (0, 1), got {threshold}")
    if examples is None:
        examples = generate_examples(n_examples, rng, config=_profile_data(model), brirs_per_room=brirs_per_room,
                                     progress=progress)
    p = model.detect(examples.patches, examples.volumes)
    pred = p >= threshold
    truth = examples.labels
    per_class = {}
    for c, name in enumerate(model.classes):
        tp = int(np.sum(pred[:, c] & truth[:, c]))
        fp = int(np.sum(pred[:, c] & ~truth[:, c]))
        fn = int(np.sum(~pred[:, c] & truth[:, c]))
        precision = tp / (tp + fp) if tp + fp else 0.0
        recall = tp / (tp + fn) if tp + fn else 0.0
        if tp + fp + fn == 0:
            f1 = 1.0
        else:
            f1 = 2 * tp / (2 * tp + fp + fn)
        per_class[name] = {"precision": round(precision, 4), "recall": round(recall, 4), "f1": round(f1, 4),
                           "support": int(truth[:, c].sum())}
    f1_macro = float(np.mean([v["f1"] for v in per_class.values()]))
    return {"f1_macro": round(f1_macro, 4), "per_class": per_class, "threshold": threshold,
            "n_examples": len(examples)}


def _profile_data(model: MelCNN) -> SoundDataConfig:
    name = model.metadata.get("profile")
    return PROFILES[name].data if name in PROFILES else SoundDataConfig()


def frame_time_ms(model: MelCNN, *, repeats: int = 300) -> float:
    """Median wall time (ms) of one frame of both ears (a batch of 2) with the current
    torch thread count (set ``torch.set_num_threads(2)`` for the paper's budget)."""
    x = torch.zeros(2, feat.MEL_FRAMES, feat.N_MELS) - 0.5
    model.eval()
    times = []
    with torch.inference_mode():
        for _ in range(20):
            model(x)
        for _ in range(repeats):
            t = time.perf_counter()
            torch.sigmoid(model(x))
            times.append(time.perf_counter() - t)
    return float(np.median(times) * 1e3)
