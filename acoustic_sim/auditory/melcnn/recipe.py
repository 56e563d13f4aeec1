"""MelCNN recipes: the network's layer sizes, the training profiles and their seed streams.

Profiles, caching, randomness
-----------------------------
``paper``: the detector of :mod:`.detector`, 40 000 training windows (about 2 860 scenes,
64 BRIRs), 14 epochs of one random ear per window, batch 128, Adam 2e-3 cosine-decayed to
1e-4. ``fast``: 16 filters, 128 units, 1 200 windows (4 BRIRs), 30 epochs; for tests only.

Measurements (the sizes, dropout and recipes compared: frame times, training times,
held-out F1): docs/notes/melcnn_recipes.md.

A model is trained on first use and cached as a checkpoint
(:mod:`~acoustic_sim.auditory.checkpoint`) in the cache folder (file
``melcnn-<profile>-v<VERSION>-<recipe ident>.pt``, :attr:`Profile.ident`); ``acoustic-sim
train melcnn`` rebuilds it. Training data come from ``SeedSequence(profile.seed).spawn(3)[0]``;
held-out validation uses stream 1 (:func:`heldout_rng`), with BRIRs at other positions and
other sound instances, and the reported evaluation (``eval paper``) stream 2
(:func:`report_rng`), which no choice looked at.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json

import numpy as np

from acoustic_sim.auditory import features as feat
from acoustic_sim.auditory.sound_data import SoundDataConfig
from acoustic_sim.errors import ConfigError

KIND = "melcnn"
"""Checkpoint ``kind``."""

VERSION = 2
"""Recipe version: bump when the data, the network or the training change (old caches are
then ignored, as the version is part of the cache file name)."""


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
