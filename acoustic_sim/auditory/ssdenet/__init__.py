"""SSDENet: one small network per frequency bin, mapping ILD/IPD to a direction-existence map.

The paper (section "Human Mimetic Sound Source Direction Estimation") gives each discrete
frequency w_i its own network SSDENet_i: 5 inputs (ILD and the two unit phasors of
:func:`acoustic_sim.auditory.features.ild_ipd`), two hidden layers and one output per
direction d_k of the grid, all with sigmoid activations::

    P(w_i)  = SSDENet_i(ILD(w_i), IPD(w_i))                 (D,)
    P(d_k)  = sum_i c_i P(d_k, w_i),   c_i = 1 if w_i is valid else 0
    d^      = argmax_k P(d_k)

The package, one concept a module (all public names are re-exported here):

``recipes``
    :class:`SSDENetProfile`, which bins get a network, and the ``paper`` / ``fast`` /
    ``quick`` profiles (:data:`PROFILES`).
``networks``
    The functional core: stacked weights of all bins, evaluated in three batched matrix
    products (:func:`ssdenet_forward`), and their initialisation.
``fusion``
    How the valid bins' maps make one P(d) (:data:`FUSIONS`): the paper's sum, or by
    default n times their geometric mean (:func:`fuse`; measurements: docs/notes/fusion.md).
``validity``
    The paper's valid bins c_i (:func:`valid_bins`) and the window-leakage rule (:data:`LEAKAGE`).
``training``
    Virtual sources through the HRTF (the paper's equations), Gaussian targets, MSE loss,
    Adam (:func:`train_weights`).
``stack``
    :class:`SSDENetStack`: the networks of a set of bins over a grid, their evaluation and
    the estimate (:class:`SSDENetEstimate`).
``bank``
    :class:`SSDENetBank`: a stack trained for one HRTF, its checkpoints and cache
    (:meth:`SSDENetBank.load_or_train`), :func:`train_bank` and :func:`train_command`.

Use::

    hrtf = HRTF.load("kemar")
    grid = DirectionGrid.paper(hrtf)
    bank = SSDENetBank.load_or_train(hrtf, grid, "paper")   # trained once (minutes), then cached
    spectra = analyze(audio).spectra                         # (K, 2, 1025)
    valid = valid_bins(spectra, noise_power, class_bins=characteristic_bins)
    est = bank.estimate(spectra, valid)                      # None: no bank bin was valid
    existence, vector, (azimuth_deg, elevation_deg) = est
"""

from acoustic_sim.auditory.ssdenet.bank import KIND, VERSION, SSDENetBank, train_bank, train_command
from acoustic_sim.auditory.ssdenet.fusion import (
    DEFAULT_FUSION,
    FUSION_FLOOR,
    FUSIONS,
    check_fusion,
    fuse,
    pool_looks,
)
from acoustic_sim.auditory.ssdenet.networks import (
    INIT_GAINS,
    PARAMETER_NAMES,
    init_weights,
    ssdenet_forward,
    weight_shapes,
)
from acoustic_sim.auditory.ssdenet.recipes import (
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
from acoustic_sim.auditory.ssdenet.stack import (
    GATHER_MAX_BINS,
    WITHIN_CACHE,
    WITHIN_MAX_BINS,
    SSDENetEstimate,
    SSDENetStack,
)
from acoustic_sim.auditory.ssdenet.training import (
    normalized_transfer,
    source_directions,
    target_table,
    train_weights,
    training_set,
)
from acoustic_sim.auditory.ssdenet.validity import LEAKAGE, noise_power_spectrum, valid_bins

__all__ = [
    "AUDIOMETRIC_HZ", "DEFAULT_FUSION", "FAST", "FUSIONS", "FUSION_FLOOR", "GATHER_MAX_BINS", "INIT_GAINS",
    "KIND", "LEAKAGE", "N_FEATURES", "PAPER", "PARAMETER_NAMES", "PROFILES", "QUICK", "VERSION", "WITHIN_CACHE",
    "WITHIN_MAX_BINS", "SSDENetBank", "SSDENetEstimate", "SSDENetProfile", "SSDENetStack", "check_fusion",
    "erb_number", "erb_spaced_bins", "fuse", "get_profile", "harmonic_bins", "init_weights",
    "noise_power_spectrum", "normalized_transfer", "pool_looks", "source_directions", "ssdenet_forward",
    "target_table", "train_bank", "train_command", "train_weights", "training_set", "valid_bins",
    "weight_shapes",
]
