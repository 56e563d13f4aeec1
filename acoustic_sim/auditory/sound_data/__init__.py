"""Binaural sound-event examples for MelCNN: training data and held-out evaluation data.

One example is what one ear-frame's detector sees: the two normalised log-mel patches
(left, right; 25 frames = 0.4 s x 128 mel bands, :func:`~acoustic_sim.auditory.features.
log_mel_patches`) of a window of a short binaural *scene*, with the classes audible in that
window as labels.

One concept a module:

- :mod:`.data_types`: the classes, the rooms, :class:`SoundDataConfig` (how scenes are
  drawn) and :class:`SoundExamples` (the labelled windows);
- :mod:`.brir_bank`: :class:`BRIRBank`, BRIRs per room for random source positions;
- :mod:`.scene_mix`: how a scene is made (sounds from a :class:`SoundPool` through the
  BRIRs, :func:`diffuse_noise`, the microphone);
- :mod:`.windows`: the per-ear audibility labels (:func:`audibility`), the characteristic
  spectra, and the windows of one scene (:func:`scene_examples`) or many
  (:func:`generate_examples`).

Everything is drawn from the ``numpy.random.Generator`` passed in: the same seed gives the
same arrays, bit for bit (on one machine; ``human_voice`` uses ``espeak-ng`` when
installed).
"""

from acoustic_sim.auditory.sound_data.brir_bank import BRIRBank
from acoustic_sim.auditory.sound_data.data_types import CLASSES, ROOMS, SoundDataConfig, SoundExamples
from acoustic_sim.auditory.sound_data.scene_mix import SoundPool, diffuse_noise
from acoustic_sim.auditory.sound_data.windows import audibility, generate_examples, scene_examples

__all__ = [
    "CLASSES",
    "ROOMS",
    "BRIRBank",
    "SoundDataConfig",
    "SoundExamples",
    "SoundPool",
    "audibility",
    "diffuse_noise",
    "generate_examples",
    "scene_examples",
]
