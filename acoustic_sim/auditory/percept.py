"""What the auditory pipeline hands on, once per ear frame: the typed percept.

A :class:`Percept` is the output of the paper's "central nervous system" for one 16 ms ear
frame: which sounds are present (MelCNN, fused over the ears) and, for each detected sound,
where it is (SSDENet's existence map over the direction grid, fused over the valid bins
of that sound, :data:`~acoustic_sim.auditory.ssdenet.FUSIONS`). Directions are in the head frame (x forward, y left, z up; azimuth
counter-clockwise from the nose, elevation up), degrees at the boundary, unit vectors
inside.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, kw_only=True)
class DirectionEstimate:
    """Where one sound comes from.

    Attributes
    ----------
    vector : numpy.ndarray
        Unit vector (3,) in the head frame of the estimated direction.
    azimuth_deg, elevation_deg : float
        The same direction in degrees (azimuth -180..180, + = left; elevation -90..90).
    existence : numpy.ndarray
        float32 (D,): P(d) fused over the valid bins (the pipeline's ``fusion``) and summed
        over frames, one value per grid direction.
    confidence : float
        0..1: how much the peak stands out, ``(max - mean) / max`` of ``existence``
        (0 for a flat map, 1 for a single non-zero direction).
    n_bins : int
        Number of frequency bins that were summed (0 means no estimate was possible).
    method : str
        ``ssdenet``, ``music`` or ``gcc-phat``.
    """

    vector: np.ndarray
    azimuth_deg: float
    elevation_deg: float
    existence: np.ndarray
    confidence: float
    n_bins: int
    method: str = "ssdenet"

    def to_json(self) -> dict:
        return {
            "azimuth_deg": round(float(self.azimuth_deg), 2),
            "elevation_deg": round(float(self.elevation_deg), 2),
            "confidence": round(float(self.confidence), 4),
            "n_bins": int(self.n_bins),
            "method": self.method,
        }


def map_estimate(existence: np.ndarray, grid, n_bins: int, method: str) -> DirectionEstimate:
    """The estimate of a map over ``grid``'s directions (D,): its argmax, with the confidence
    ``(max - mean) / max`` (0 for a map without a positive value)."""
    k = int(np.argmax(existence))
    top = float(existence[k])
    confidence = 0.0 if top <= 0 else float(np.clip((top - float(existence.mean())) / top, 0.0, 1.0))
    return DirectionEstimate(
        vector=grid.vectors[k].copy(), azimuth_deg=float(grid.azimuth_deg[k]), elevation_deg=float(grid.elevation_deg[k]),
        existence=np.asarray(existence, np.float32), confidence=confidence, n_bins=int(n_bins), method=method,
    )


def music_estimate(result, grid) -> DirectionEstimate | None:
    """A MUSIC analysis (:class:`~acoustic_sim.auditory.baselines.Music`) as a DirectionEstimate
    over ``grid``; None when it was silent."""
    if result.silent:
        return None
    return map_estimate(np.asarray(result.spectrum, np.float32), grid, len(result.bins), "music")


def gcc_estimate(result) -> DirectionEstimate | None:
    """A GCC-PHAT analysis (an azimuth in the horizontal plane) as a DirectionEstimate; None
    when it was silent."""
    if result.silent:
        return None
    from acoustic_sim.frames import sph_to_vec, vec_to_sph

    v = sph_to_vec(result.azimuth_deg, 0.0)
    az, el = vec_to_sph(v)
    return DirectionEstimate(vector=v, azimuth_deg=float(az), elevation_deg=float(el), existence=np.zeros(0, np.float32),
                             confidence=1.0, n_bins=0, method="gcc-phat")


@dataclass(frozen=True, kw_only=True)
class Percept:
    """The pipeline's output for one ear frame.

    Attributes
    ----------
    frame : int
        Ear frame number k (frame k ends at ``frames.frame_end_sample(k)``).
    time_s : float
        End time of the frame in seconds on the sample clock.
    classes : tuple of str
        Class names, the order of ``probabilities``.
    probabilities : numpy.ndarray
        float32 (C,): fused existence probability of each class, 0..1.
    detected : tuple of str
        Classes whose probability is at least the pipeline's threshold, most likely first.
    directions : dict of str to DirectionEstimate
        One estimate per detected class that had valid bins.
    mel : numpy.ndarray
        float32 (2, N_MELS): the newest frame of the normalised log-mel input (left, right),
        for display.
    volume : numpy.ndarray
        float64 (2,): the ear volumes V_l, V_r used for the fusion.
    tracked : dict of str to TrackedDirection
        With a tracker (``AuditoryPipeline(tracker=)``): the world-frame direction of every
        sound heard so far this episode (:mod:`~acoustic_sim.auditory.tracker`), its view
        from the head's latest pose and the front-back decision; empty without one.
    """

    frame: int
    time_s: float
    classes: tuple[str, ...]
    probabilities: np.ndarray
    detected: tuple[str, ...]
    directions: dict = field(default_factory=dict)
    mel: np.ndarray | None = None
    volume: np.ndarray | None = None
    tracked: dict = field(default_factory=dict)

    def probability(self, name: str) -> float:
        return float(self.probabilities[self.classes.index(name)])

    def to_json(self) -> dict:
        return {
            "t": round(float(self.time_s), 6),
            "frame": int(self.frame),
            "probabilities": {c: round(float(p), 4) for c, p in zip(self.classes, self.probabilities)},
            "detected": list(self.detected),
            "directions": {c: d.to_json() for c, d in self.directions.items()},
            **({"tracked": {c: d.to_json() for c, d in self.tracked.items()}} if self.tracked else {}),
        }
