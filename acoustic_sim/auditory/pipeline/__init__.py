"""The auditory pipeline: audio blocks in, percepts out (DESIGN.md section 1).

Modules
-------
settings
    :class:`PipelineSettings`, the detection, validity, precedence and attribution rules.
rows
    The localizable sounds (the classes, then attended sounds) and their bins.
streaming
    :class:`AuditoryPipeline`: one :class:`~acoustic_sim.auditory.percept.Percept` per ear frame.
offline
    Whole recordings: the paper's localization (SSDENet, MUSIC, GCC-PHAT) and detection.

Measurements behind the rules: docs/notes/pipeline_rules.md.
"""

from acoustic_sim.auditory.pipeline.offline import METHODS, detect_recording
from acoustic_sim.auditory.pipeline.settings import (
    ADDED_MS,
    COHERENCE,
    COHERENCE_FRAMES,
    DIRECTION_FRAMES,
    ONSET_RATIO,
    PRECEDENCE,
    SPECIFICITY_BAND_HZ,
    VALIDITY_FACTOR,
    PipelineSettings,
)
from acoustic_sim.auditory.pipeline.streaming import AuditoryPipeline, microphone_noise_power

__all__ = [
    "ADDED_MS",
    "COHERENCE",
    "COHERENCE_FRAMES",
    "DIRECTION_FRAMES",
    "METHODS",
    "ONSET_RATIO",
    "PRECEDENCE",
    "SPECIFICITY_BAND_HZ",
    "VALIDITY_FACTOR",
    "AuditoryPipeline",
    "PipelineSettings",
    "detect_recording",
    "microphone_noise_power",
]
