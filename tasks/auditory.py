"""The tasks' ears and auditory pipeline: shared models, one fresh pipeline per env.

Loading (or, on first use, training) the SSDENet bank and the MelCNN of a profile takes
seconds; their weights are only read, so every env of a process shares one set per
(HRTF, profile) (:func:`load_models`), and each env gets its own streaming
:class:`~acoustic_sim.auditory.pipeline.AuditoryPipeline` over them (:func:`make_pipeline`).
:class:`TorchThreads` keeps torch to one thread while the pipeline runs.

Torch and the auditory modules are imported on first use, not when the tasks are imported.
"""

from __future__ import annotations

import functools

import numpy as np

from acoustic_sim.errors import ConfigError

PROFILES = ("paper", "fast")
"""Auditory pipeline profiles an env accepts."""


@functools.cache
def load_hrtf(name: str):
    """The HRTF ``name`` (``"kemar"``, ``"spherical"``, a SOFA path), loaded once per process."""
    from acoustic_sim.acoustics.hrtf import HRTF

    return HRTF.load(name)


@functools.cache
def load_models(hrtf_name: str, profile: str):
    """Trained models of a profile, loaded (or trained and cached) once per process.

    Returns
    -------
    ears : HRTF
    grid : DirectionGrid
        The paper's direction grid for ``ears``.
    bank : SSDENetBank
    cnn : MelCNN
    """
    from acoustic_sim.auditory.melcnn import MelCNN
    from acoustic_sim.auditory.ssdenet import SSDENetBank
    from acoustic_sim.directions import DirectionGrid

    ears = load_hrtf(hrtf_name)
    grid = DirectionGrid.paper(ears)
    bank = SSDENetBank.load_or_train(ears, grid, profile, progress=True)
    cnn = MelCNN.load_or_train(profile, progress=True)
    return ears, grid, bank, cnn


def microphone_noise_power() -> np.ndarray:
    """The microphone's self-noise power per bin (2, 1025), full-scale units: the floor of
    the pipeline's noise reference (:func:`acoustic_sim.loop.microphone_floor`, computed once)."""
    from acoustic_sim.loop import microphone_floor

    return microphone_floor()


def make_pipeline(profile: str = "paper", hrtf: str = "kemar", coverage: float = 0.0, specificity: float = 0.0,
                  onset_windows: int = 1, fusion: str = "product", precedence: str | None = "wavefront"):
    """A fresh :class:`~acoustic_sim.auditory.pipeline.AuditoryPipeline` (its own streaming
    state) over the process's shared models of ``profile``; ``coverage`` and ``specificity``
    are the pipeline's attribution rules (a frame counts for a class when it covers that
    fraction of its bins, and when that fraction of its onset's energy lies in them),
    ``onset_windows`` the windows it takes at a rising onset, ``fusion`` how it fuses a
    frame's bins (``"product"`` or ``"sum"``), ``precedence`` its evidence rule. It tracks the sounds in the world frame
    (:mod:`~acoustic_sim.auditory.tracker`; the hearing loop gives it the head's pose)."""
    from acoustic_sim.auditory.pipeline import AuditoryPipeline

    if profile not in PROFILES:
        raise ConfigError(f"unknown pipeline profile {profile!r}; valid: {', '.join(PROFILES)}")
    ears, grid, bank, cnn = load_models(hrtf, profile)
    return AuditoryPipeline(hrtf=ears, grid=grid, ssdenet=bank, melcnn=cnn, noise_power=microphone_noise_power(),
                            coverage=coverage, specificity=specificity, onset_windows=onset_windows, fusion=fusion,
                            precedence=precedence, tracker=True)


class TorchThreads:
    """Run a block with at most ``n`` torch threads (restored after).

    The pipeline's networks are small: per frame, torch's OpenMP workers and the renderer's
    OpenBLAS workers busy-wait against each other on a 2-core machine (measured: 50 ms per
    frame instead of 1.5 ms); one torch thread avoids it.

    Parameters
    ----------
    n : int or None
        Torch threads inside the block; None leaves torch's setting.
    """

    def __init__(self, n: int | None) -> None:
        self.n = n

    def __enter__(self):
        if self.n is not None:
            import torch

            self._old = torch.get_num_threads()
            if self._old != self.n:
                torch.set_num_threads(self.n)
        return self

    def __exit__(self, *exc) -> None:
        if self.n is not None and self._old != self.n:
            import torch

            torch.set_num_threads(self._old)


__all__ = ["PROFILES", "TorchThreads", "load_hrtf", "load_models", "make_pipeline", "microphone_noise_power"]
