"""The MelCNN network: the logMel-CNN detector of one ear, its inference and its checkpoints.

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
leaves about half the budget for a loaded machine
(:func:`~acoustic_sim.auditory.melcnn.scoring.frame_time_ms` measures it again;
``acoustic-sim train melcnn`` reports it).

Checkpoints: the ``state_dict`` plus JSON metadata (:meth:`MelCNN.save`), cached per recipe
(:mod:`~acoustic_sim.auditory.melcnn.recipe`); a missing cache is filled by
:func:`~acoustic_sim.auditory.melcnn.fitting.train`.
"""

from __future__ import annotations

import dataclasses
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
from acoustic_sim.auditory.melcnn.binaural import fuse
from acoustic_sim.auditory.melcnn.recipe import KIND, VERSION, NetConfig, get_profile
from acoustic_sim.auditory.sound_data import CLASSES
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE


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
        from acoustic_sim.auditory.melcnn.fitting import train  # imports this module

        model = train(profile, progress=progress)
        model.save(path)
        return model


def _mel_signature() -> dict:
    """The log-mel front end a model was trained on (a checkpoint must match it)."""
    return {"n_mels": feat.N_MELS, "frames": feat.MEL_FRAMES, "fmin_hz": feat.MEL_FMIN_HZ,
            "fmax_hz": feat.MEL_FMAX_HZ, "range_db": feat.MEL_RANGE_DB}
