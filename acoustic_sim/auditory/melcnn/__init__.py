"""MelCNN: the paper's binaural environmental sound detector.

Section "Binaural Environmental Sound Detection" of Omura et al. 2022: a logMel-CNN
(Piczak 2015) per ear on the normalised 25 x 128 log-mel patch, a sigmoid existence
probability per class, the two ears fused by their volumes, and per class the
characteristic frequency bins that select the bins SSDENet sums over.

One concept a module:

- :mod:`.recipe`: layer sizes (:class:`NetConfig`), training profiles (:class:`Profile`,
  ``paper`` and ``fast``) and their seed streams;
- :mod:`.detector`: the network (:class:`MelCNN`), inference, checkpoints and the cache;
- :mod:`.binaural`: the volume-weighted fusion of the two ears (:func:`fuse`);
- :mod:`.characteristic`: each class's characteristic bins (:func:`characteristic_bins`);
- :mod:`.fitting`: the paper's KL loss and training (:func:`train`);
- :mod:`.scoring`: held-out F-score (:func:`evaluate`) and frame time.

The training data come from :mod:`acoustic_sim.auditory.sound_data`; ``acoustic-sim train
melcnn`` (:mod:`acoustic_sim.cli_auditory`) rebuilds the cached model. Measurements:
docs/notes/melcnn_recipes.md.
"""

from acoustic_sim.auditory.melcnn.binaural import fuse, fuse_unchecked, patch_volumes
from acoustic_sim.auditory.melcnn.characteristic import characteristic_bins
from acoustic_sim.auditory.melcnn.detector import MelCNN
from acoustic_sim.auditory.melcnn.fitting import kl_divergence_loss, train
from acoustic_sim.auditory.melcnn.recipe import (
    KIND,
    PROFILES,
    VERSION,
    NetConfig,
    Profile,
    get_profile,
    heldout_rng,
    report_rng,
    training_rng,
)
from acoustic_sim.auditory.melcnn.scoring import evaluate, frame_time_ms

__all__ = [
    "KIND",
    "PROFILES",
    "VERSION",
    "MelCNN",
    "NetConfig",
    "Profile",
    "characteristic_bins",
    "evaluate",
    "frame_time_ms",
    "fuse",
    "fuse_unchecked",
    "get_profile",
    "heldout_rng",
    "kl_divergence_loss",
    "patch_volumes",
    "report_rng",
    "train",
    "training_rng",
]
