"""Whole recordings: the paper's per-frame localization (SSDENet, MUSIC, GCC-PHAT) and detection.

Unlike the streaming pipeline these see every frame at once and keep the paper's rule
alone (no precedence, no attribution rules): the paper's experiments and the
``localize`` / ``detect`` commands (:mod:`acoustic_sim.auditory.recording` streams long files).
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.auditory.baselines import GccPhat, Music
from acoustic_sim.auditory.features import MEL_FRAMES, ear_volume, log_mel_patches
from acoustic_sim.auditory.frontend import N_BINS, analyze
from acoustic_sim.auditory.percept import gcc_estimate, music_estimate
from acoustic_sim.auditory.percept import map_estimate as _estimate
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

METHODS = ("ssdenet", "music", "gcc-phat")
"""Localization methods of :meth:`AuditoryPipeline.localize <acoustic_sim.auditory.pipeline.AuditoryPipeline.localize>`."""


def check_method(method: str) -> None:
    if method not in METHODS:
        raise ConfigError(f"unknown localization method {method!r}; valid: {', '.join(METHODS)}")


def _frames(audio):
    frames = analyze(audio)
    if len(frames) == 0:
        raise ConfigError(f"the recording is shorter than one ear frame ({int(np.ceil(SAMPLE_RATE / 62.5))} samples)")
    return frames


class Baselines:
    """MUSIC and GCC-PHAT estimators over frames of spectra, built on first use.

    Parameters
    ----------
    hrtf : HRTF
        MUSIC's steering vectors and GCC-PHAT's delay-to-azimuth map.
    grid : DirectionGrid
        MUSIC's output directions.
    """

    def __init__(self, hrtf, grid) -> None:
        self.hrtf = hrtf
        self.grid = grid
        self._music: Music | None = None
        self._gcc: GccPhat | None = None

    def estimator(self, method: str):
        """A function of spectra (K, 2, 1025) -> DirectionEstimate or None (silence)."""
        if method == "music":
            if self._music is None:
                self._music = Music(self.hrtf, self.grid)
            music, grid = self._music, self.grid
            return lambda x: music_estimate(music.analyze(x), grid)
        if self._gcc is None:
            self._gcc = GccPhat(self.hrtf)
        gcc = self._gcc
        return lambda x: gcc_estimate(gcc.analyze(x))


def localize_recording(pipe, audio, *, method: str = "ssdenet", sound: str | None = None, window: int = MEL_FRAMES):
    """Direction estimates of a whole (2, n) recording with ``pipe``'s models and validity
    rule: :meth:`AuditoryPipeline.localize <acoustic_sim.auditory.pipeline.AuditoryPipeline.localize>`."""
    check_method(method)
    frames = _frames(audio)
    x = frames.spectra
    if method == "ssdenet":
        valid = pipe.valid_bins(x)
        if sound is not None:
            if sound not in pipe.classes:
                raise ConfigError(f"unknown sound class {sound!r}; valid: {', '.join(pipe.classes)}")
            mask = np.zeros(N_BINS, bool)
            mask[pipe.sound_bins(sound)] = True
            valid = valid & mask
        maps, n_valid = pipe.ssdenet.frame_maps(x, valid, pipe.settings.fusion)
        csum = np.cumsum(maps, axis=0)
        nsum = np.cumsum(n_valid)
        per_frame = []
        for i, t in enumerate(frames.time_s):
            lo = i - window
            m = csum[i] - (csum[lo] if lo >= 0 else 0.0)
            nb = int(nsum[i] - (nsum[lo] if lo >= 0 else 0))
            per_frame.append((float(t), _estimate(m, pipe.grid, nb, method) if nb else None))
        overall = _estimate(maps.sum(axis=0), pipe.grid, int(n_valid.sum()), method) if n_valid.sum() else None
        return per_frame, overall
    est = pipe.baselines.estimator(method)
    per_frame = []
    for i, t in enumerate(frames.time_s):
        per_frame.append((float(t), est(x[max(0, i - window + 1) : i + 1])))
    return per_frame, est(x)


def detect_recording(melcnn, audio):
    """Class probabilities of a whole (2, n) recording.

    Returns
    -------
    times : numpy.ndarray (K,)
        Frame times (s).
    probabilities : numpy.ndarray float32 (K, C)
        Fused probabilities per frame (each from the 25 frames ending there).
    overall : numpy.ndarray float32 (C,)
        The maximum over frames: the probability that each class occurs in the file.
    """
    frames = _frames(audio)
    patches = log_mel_patches(frames.spectra)
    vol = ear_volume(frames.spectra)  # (K, 2)
    kernel = np.ones(MEL_FRAMES) / MEL_FRAMES
    # Mean volume over each patch's frames (frames before the start count as silent).
    vol = np.stack([np.convolve(vol[:, e], kernel)[: len(vol)] for e in range(2)], axis=1)
    probs = np.concatenate([melcnn.detect(patches[i : i + 256], vol[i : i + 256]) for i in range(0, len(patches), 256)])
    probs = probs.astype(np.float32)
    return frames.time_s, probs, probs.max(axis=0)
