"""MelCNN evaluation: the paper's detection F-score on held-out windows, and the frame time."""

from __future__ import annotations

import time

import numpy as np
import torch

from acoustic_sim.auditory import features as feat
from acoustic_sim.auditory.melcnn.detector import MelCNN
from acoustic_sim.auditory.melcnn.recipe import PROFILES
from acoustic_sim.auditory.sound_data import SoundDataConfig, SoundExamples, generate_examples
from acoustic_sim.errors import ConfigError


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
