"""The streaming pipeline's settings: one kw_only dataclass, validated once (DESIGN.md section 3).

Each field says its unit and range; what the rules gave on the tasks is in
docs/notes/pipeline_rules.md.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from acoustic_sim.auditory.features import MEL_FRAMES
from acoustic_sim.auditory.ssdenet import DEFAULT_FUSION, LEAKAGE, check_fusion
from acoustic_sim.errors import ConfigError

VALIDITY_FACTOR = 10.0
"""The paper's threshold: a bin is valid when its power exceeds 10 x the noise's."""

DIRECTION_FRAMES = 12
"""Frames (0.19 s) of existence maps that a detected class's direction sums by default."""

ONSET_RATIO = 2.0
"""The ``"ratio"`` precedence gate: a bin's power must have doubled (+3 dB) since the last frame."""

SPECIFICITY_BAND_HZ = (300.0, 12000.0)
"""The band (Hz) over which ``specificity`` measures an onset's energy: the networks' range."""

ADDED_MS = 10.0
"""With precedence and ``specificity``: the segments (ms) before and after an onset whose power
difference is the energy the onset added
(:meth:`~acoustic_sim.auditory.precedence.FirstWavefront.take_added`)."""

COHERENCE = 0.97
"""The ``"coherence"`` precedence gate: a bin counts when the interaural coherence of its last
:data:`COHERENCE_FRAMES` frames is at least this."""

COHERENCE_FRAMES = 4
"""Frames (64 ms) over which the ``"coherence"`` gate averages the interaural cross-spectrum."""

PRECEDENCE = ("wavefront", "ratio", "coherence", "wavefront+coherence", None)
"""Precedence modes of the streaming pipeline (:class:`PipelineSettings`); the first is the default."""

WAVEFRONT_MODES = ("wavefront", "wavefront+coherence")
"""The precedence modes that take a frame's cues from the first wavefront of its onsets."""

COHERENCE_MODES = ("coherence", "wavefront+coherence")
"""The precedence modes that take the cues of frames without onsets where the ears agree."""


def _unit(value, name: str) -> None:
    if not (value is not None and np.isfinite(value) and 0.0 <= value <= 1.0):
        raise ConfigError(f"{name} must be in [0, 1], got {value}")


@dataclass(frozen=True, kw_only=True)
class PipelineSettings:
    """How the streaming pipeline detects, selects evidence and localizes.

    Every field is checked when the settings are made (:class:`~acoustic_sim.errors.ConfigError`
    naming the field). ``AuditoryPipeline(..., coverage=0.5)`` is shorthand for
    ``AuditoryPipeline(..., settings=PipelineSettings(coverage=0.5))``.
    """

    threshold: float = 0.5
    """Detection threshold on the fused class probability; (0, 1)."""
    factor: float = VALIDITY_FACTOR
    """Validity factor over the noise power (the paper: 10); > 0."""
    leakage: float = LEAKAGE
    """Validity factor over the window's sidelobe leakage from other bins (0: off, the paper's
    rule alone): the neighbours of a strong tone carry its interaural cues, not their own
    (:func:`~acoustic_sim.auditory.ssdenet.valid_bins`); >= 0."""
    direction_frames: int = DIRECTION_FRAMES
    """Frames whose existence maps a class's direction sums (1 = the current frame only; 12 =
    0.19 s); integer in 1..25 (the MelCNN's patch)."""
    precedence: str | None = "wavefront"
    """Which frames and cues give direction evidence, one of :data:`PRECEDENCE`:
    ``"wavefront"`` (the first wavefront of onsets), ``"ratio"`` (bins whose power rose
    ``onset_ratio`` times since the last frame), ``"coherence"`` (bins whose interaural
    coherence over :data:`COHERENCE_FRAMES` frames is at least ``coherence``: the direct sound
    where the room's diffuse field has decorrelated the ears; for sounds without onsets),
    ``"wavefront+coherence"`` (the first wavefront at onsets, the coherent bins between them),
    or None (the paper's rule alone)."""
    onset_ratio: float = ONSET_RATIO
    """The ``"ratio"`` mode's power factor; >= 1."""
    coherence: float = COHERENCE
    """The ``"coherence"`` modes' threshold on the interaural coherence; 0..1."""
    coverage: float = 0.0
    """A frame counts for a class only when its valid bins cover at least this fraction of the
    class's bank bins (0: every frame; the cabin tasks use 0.5); 0..1."""
    specificity: float = 0.0
    """A frame counts for a class only when at least this fraction of the energy its onset
    added (:data:`ADDED_MS`; the frame's energy without precedence;
    :data:`SPECIFICITY_BAND_HZ`, both ears) lies in the class's characteristic bins (0: off;
    ReverseAlarm uses 0.2): a broadband onset (a horn) while a tonal alarm is detected lights
    up the alarm's bins too, but its energy hardly lies there; 0..1."""
    onset_windows: int = 1
    """With a wavefront mode: windows taken at a rising onset (1 ms apart), whose existence
    maps are pooled per bin (:func:`~acoustic_sim.auditory.ssdenet.pool_looks`); integer >= 1."""
    fusion: str = DEFAULT_FUSION
    """How a frame's bins are fused: ``"product"`` (n times their geometric mean) or ``"sum"``
    (the paper's equation); :data:`~acoustic_sim.auditory.ssdenet.FUSIONS`."""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.threshold) and 0.0 < self.threshold < 1.0):
            raise ConfigError(f"threshold must be in (0, 1), got {self.threshold}")
        if not (np.isfinite(self.factor) and self.factor > 0):
            raise ConfigError(f"factor must be > 0, got {self.factor}")
        if not (self.leakage is not None and np.isfinite(self.leakage) and self.leakage >= 0):
            raise ConfigError(f"leakage must be >= 0, got {self.leakage}")
        if self.precedence not in PRECEDENCE:
            raise ConfigError(f"precedence must be one of {PRECEDENCE}, got {self.precedence!r}")
        _unit(self.coherence, "coherence")
        if not (self.onset_ratio is not None and np.isfinite(self.onset_ratio) and self.onset_ratio >= 1.0):
            raise ConfigError(f"onset_ratio must be >= 1, got {self.onset_ratio}")
        _unit(self.coverage, "coverage")
        _unit(self.specificity, "specificity")
        if not (isinstance(self.onset_windows, (int, np.integer)) and self.onset_windows >= 1):
            raise ConfigError(f"onset_windows must be an integer >= 1, got {self.onset_windows!r}")
        d = self.direction_frames
        if not isinstance(d, (int, np.integer)) or not 1 <= d <= MEL_FRAMES:
            raise ConfigError(f"direction_frames must be an integer in 1..{MEL_FRAMES}, got {d!r}")
        check_fusion(self.fusion)
        for name in ("threshold", "factor", "leakage", "onset_ratio", "coherence", "coverage", "specificity"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "direction_frames", int(d))
        object.__setattr__(self, "onset_windows", int(self.onset_windows))


def merged_settings(settings: PipelineSettings | None, fields: dict) -> PipelineSettings:
    """``settings`` (default: the defaults) with the given fields replaced; a field given as
    None keeps its default (``direction_frames=None``)."""
    base = PipelineSettings() if settings is None else settings
    if not isinstance(base, PipelineSettings):
        raise ConfigError(f"settings must be a PipelineSettings, got {type(base).__name__}")
    known = {f.name for f in dataclasses.fields(PipelineSettings)}
    unknown = sorted(set(fields) - known)
    if unknown:
        raise TypeError(f"unknown pipeline setting(s) {', '.join(unknown)}; valid: {', '.join(sorted(known))}")
    if fields.get("direction_frames", 0) is None:
        fields = {k: v for k, v in fields.items() if k != "direction_frames"}
    return dataclasses.replace(base, **fields) if fields else base
