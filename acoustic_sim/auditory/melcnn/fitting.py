"""MelCNN training: the paper's loss and the training loop of a profile.

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

Torch's global RNG (weight init, dropout) is seeded inside :func:`torch.random.fork_rng`, so
training is deterministic and leaves the caller's torch state alone.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import torch
import torch.nn.functional as F

from acoustic_sim.acoustics import sounds
from acoustic_sim.auditory.melcnn.characteristic import characteristic_bins
from acoustic_sim.auditory.melcnn.detector import MelCNN
from acoustic_sim.auditory.melcnn.recipe import Profile, get_profile, training_rng
from acoustic_sim.auditory.sound_data import SoundExamples, generate_examples
from acoustic_sim.errors import ConfigError


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
