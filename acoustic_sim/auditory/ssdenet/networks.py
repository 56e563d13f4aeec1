"""The functional core of an SSDENet bank: stacked weights and one batched forward pass.

The networks of all chosen bins are stored as stacked weights ``w1 (n_bins, 5, H)``,
``w2 (n_bins, H, H)``, ``w3 (n_bins, H, D)`` (biases ``(n_bins, 1, .)``) and evaluated
together by three ``torch.baddbmm`` calls (:func:`ssdenet_forward`), never by a loop over
bins. Adam is element-wise and the loss is the sum of the per-bin mean squared errors, so
training the stack is exactly training each network on its own.
"""

from __future__ import annotations

import math

import torch

from acoustic_sim.auditory.ssdenet.recipes import N_FEATURES
from acoustic_sim.errors import ConfigError

PARAMETER_NAMES = ("w1", "b1", "w2", "b2", "w3", "b3")
"""The stacked weights and biases of the three layers, in the order of :func:`ssdenet_forward`."""


def weight_shapes(n_bins: int, hidden: int, n_outputs: int) -> dict[str, tuple[int, ...]]:
    """The shape of each stacked weight (:data:`PARAMETER_NAMES`) of ``n_bins`` networks with
    ``hidden`` units H per hidden layer and ``n_outputs`` outputs D."""
    per_bin = {"w1": (N_FEATURES, hidden), "b1": (1, hidden), "w2": (hidden, hidden), "b2": (1, hidden),
               "w3": (hidden, n_outputs), "b3": (1, n_outputs)}
    return {name: (int(n_bins),) + tuple(int(v) for v in per_bin[name]) for name in PARAMETER_NAMES}

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
    shapes = weight_shapes(n_bins, hidden, n_outputs)
    fan_in = {"1": N_FEATURES, "2": hidden, "3": hidden}
    out = {}
    for name in PARAMETER_NAMES:
        layer = name[1]
        bound = INIT_GAINS[int(layer) - 1] / math.sqrt(fan_in[layer])
        t = torch.empty(shapes[name], dtype=torch.float32)
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
