"""Running estimates of a recording pushed in chunks of ear frames: what ``acoustic-sim
localize`` and ``detect`` keep between chunks (:mod:`~acoustic_sim.auditory.recording`
reads the file and cuts the frames).

Each track keeps only the last ``window`` frames (spectra or existence maps), the last 24 mel
frames for the MelCNN's patches, and running sums for the overall result, so its memory
does not grow with the file. Agreement with the in-memory functions
(:meth:`AuditoryPipeline.localize <acoustic_sim.auditory.pipeline.AuditoryPipeline.localize>`,
:func:`~acoustic_sim.auditory.pipeline.detect_recording`), which hold the whole recording:

- per frame, detection and MUSIC / GCC-PHAT: each frame's result is computed from the same
  frames (:data:`~acoustic_sim.auditory.recording.CHUNK_FRAMES` is the MelCNN batch of
  :func:`detect_recording`); the tests allow float32 rounding (1e-6);
- per frame, SSDENet: the running sum of the last ``window`` existence maps is summed
  directly (float64) where the in-memory path takes differences of a float32 cumulative sum
  over the whole recording, which loses digits as the recording grows (at an hour the sum is
  ~10^7 times a frame's map, and float32 keeps ~7 digits); the two agree to float32
  rounding on short recordings;
- overall: sums over all frames (maps, correlation matrices, cross-spectra) are accumulated
  per chunk in float64 / complex128 instead of in one float32 sum; they agree to float32
  rounding (tests: 1e-5 relative).
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.auditory.frontend import N_BINS, Frames
from acoustic_sim.auditory.percept import gcc_estimate, music_estimate
from acoustic_sim.errors import ConfigError

DETECT_BATCH = 16
"""Frames whose patches the MelCNN runs on at once (both ears: 32 patches). The paper model's
activations cost about 1 MB a patch at peak; 16 frames keep ``detect`` under 450 MB and are
faster than 64 (docs/notes/streaming.md)."""


def _window_sums(history: np.ndarray, new: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``new`` (K, ...), the float64 sum of it and the ``window - 1`` rows before it,
    given the ``window - 1`` rows before ``new`` (``history``, zeros before the recording).
    Returns the sums (K, ...) and the new history."""
    rows = np.concatenate([history, new])
    csum = np.cumsum(rows, axis=0, dtype=np.float64)
    lead = np.zeros((1,) + rows.shape[1:])
    csum = np.concatenate([lead, csum])
    k = new.shape[0]
    sums = csum[window : window + k] - csum[:k]
    return sums, rows[rows.shape[0] - (window - 1) :].copy() if window > 1 else rows[:0].copy()


class SSDENetTrack:
    """``AuditoryPipeline.localize(method="ssdenet")`` of a recording pushed in chunks of frames.

    Keeps the last ``window - 1`` frames' maps and the sum of all of them. ``pipe`` is an
    :class:`~acoustic_sim.auditory.pipeline.AuditoryPipeline` (its SSDENet bank, validity
    test and fusion; MelCNN's characteristic bins when ``sound`` is given).
    """

    method = "ssdenet"

    def __init__(self, pipe, *, sound: str | None = None, window: int = 25) -> None:
        if window < 1:
            raise ConfigError(f"window must be >= 1, got {window}")
        self.pipe = pipe
        self.window = int(window)
        self.mask = None
        if sound is not None:
            if sound not in pipe.classes:
                raise ConfigError(f"unknown sound class {sound!r}; valid: {', '.join(pipe.classes)}")
            self.mask = np.zeros(N_BINS, bool)
            self.mask[pipe.sound_bins(sound)] = True
        d = len(pipe.grid)
        self._maps = np.zeros((self.window - 1, d), np.float32)
        self._counts = np.zeros(self.window - 1, np.int64)
        self._total = np.zeros(d)
        self._total_bins = 0
        self.frames = 0

    def push(self, frames: Frames) -> list:
        """(time_s, DirectionEstimate or None) of each frame: the estimate of its last ``window`` frames."""
        from acoustic_sim.auditory.percept import map_estimate

        x = frames.spectra
        valid = self.pipe.valid_bins(x)
        if self.mask is not None:
            valid = valid & self.mask
        maps, n_valid = self.pipe.ssdenet.frame_maps(x, valid, self.pipe.settings.fusion)
        sums, self._maps = _window_sums(self._maps, maps, self.window)
        counts, self._counts = _window_sums(self._counts, n_valid, self.window)
        self._total += maps.sum(axis=0, dtype=np.float64)
        self._total_bins += int(n_valid.sum())
        self.frames += len(frames)
        grid = self.pipe.grid
        return [(float(t), map_estimate(m.astype(np.float32), grid, int(nb), self.method) if nb else None)
                for t, m, nb in zip(frames.time_s, sums, np.rint(counts).astype(np.int64))]

    def overall(self):
        """The estimate from all frames together; None when no bin was ever valid."""
        from acoustic_sim.auditory.percept import map_estimate

        if not self._total_bins:
            return None
        return map_estimate(self._total.astype(np.float32), self.pipe.grid, self._total_bins, self.method)


class BaselineTrack:
    """``AuditoryPipeline.localize(method="music" | "gcc-phat")`` of a recording pushed in chunks.

    Needs only the HRTF (MUSIC's steering vectors, GCC-PHAT's lag calibration) and the grid:
    no learned model. Keeps the last ``window - 1`` frames' spectra and, for the overall
    estimate, the sum of the correlation matrices (MUSIC) or of the cross-spectrum (GCC-PHAT).
    """

    def __init__(self, method: str, hrtf, grid, *, window: int = 25) -> None:
        from acoustic_sim.auditory.baselines import GccPhat, Music

        if method not in ("music", "gcc-phat"):
            raise ConfigError(f"unknown baseline method {method!r}; valid: music, gcc-phat")
        if window < 1:
            raise ConfigError(f"window must be >= 1, got {window}")
        self.method = method
        self.grid = grid
        self.window = int(window)
        self.music = Music(hrtf, grid) if method == "music" else None
        self.gcc = GccPhat(hrtf) if method == "gcc-phat" else None
        self._tail = np.zeros((0, 2, N_BINS), np.complex64)
        self._sum = None
        self.frames = 0

    def _estimate(self, x: np.ndarray):
        if self.music is not None:
            return music_estimate(self.music.analyze(x), self.grid)
        return gcc_estimate(self.gcc.analyze(x))

    def push(self, frames: Frames) -> list:
        """(time_s, DirectionEstimate or None) of each frame, from its last ``window`` frames."""
        x = frames.spectra
        rows = np.concatenate([self._tail, x])
        lead = self._tail.shape[0]
        out = []
        for j, t in enumerate(frames.time_s):
            i = lead + j
            out.append((float(t), self._estimate(rows[max(0, i - self.window + 1) : i + 1])))
        self._tail = rows[max(0, rows.shape[0] - (self.window - 1)) :].copy() if self.window > 1 else rows[:0].copy()
        if self.music is not None:
            xb = x[:, :, self.music.bins].astype(np.complex128)
            part = np.einsum("kib,kjb->bij", xb, np.conj(xb))
        else:
            part = np.sum(x[:, 0].astype(np.complex128) * np.conj(x[:, 1].astype(np.complex128)), axis=0)
        self._sum = part if self._sum is None else self._sum + part
        self.frames += len(frames)
        return out

    def overall(self):
        """The estimate from all frames together; None for silence (or no frame)."""
        if self._sum is None:
            return None
        if self.music is not None:
            # In the in-memory path's precision (complex64), summed more precisely.
            return music_estimate(self.music.analyze_correlation((self._sum / self.frames).astype(np.complex64)), self.grid)
        return gcc_estimate(self.gcc.analyze_cross(self._sum.astype(np.complex64)))


class DetectTrack:
    """:func:`~acoustic_sim.auditory.pipeline.detect_recording` of a recording pushed in chunks.

    Keeps the last 24 frames' mel power and ear volumes (a patch is 25 frames) and the
    running maximum of each class's probability.
    """

    def __init__(self, melcnn) -> None:
        from acoustic_sim.auditory.features import MEL_FRAMES, N_MELS

        self.melcnn = melcnn
        self.classes = tuple(melcnn.classes)
        self._n = MEL_FRAMES
        self._mel = np.zeros((MEL_FRAMES - 1, 2, N_MELS), np.float32)
        self._vol = np.zeros((0, 2))
        self._max = None
        self.frames = 0

    def push(self, frames: Frames) -> tuple[np.ndarray, np.ndarray]:
        """Times (K,) and fused probabilities float32 (K, C) of the frames (the MelCNN runs
        once on the chunk: push at most :data:`~acoustic_sim.auditory.recording.CHUNK_FRAMES`
        frames at a time)."""
        from acoustic_sim.auditory.features import ear_volume, mel_power, normalize_log_mel

        x = frames.spectra
        k = x.shape[0]
        if k == 0:
            return frames.time_s, np.zeros((0, len(self.classes)), np.float32)
        n = self._n
        padded = np.concatenate([self._mel, mel_power(x)])  # (n - 1 + K, 2, M)
        win = np.lib.stride_tricks.sliding_window_view(padded, n, axis=0)  # (K, 2, M, n)
        patches = normalize_log_mel(win.transpose(0, 1, 3, 2))
        self._mel = padded[-(n - 1) :].copy()
        vol = ear_volume(x)  # (K, 2)
        kernel = np.ones(n) / n
        lead = self._vol.shape[0]
        joined = np.concatenate([self._vol, vol])
        # Mean volume over each patch's frames (frames before the start count as silent): the
        # entries of np.convolve over the whole recording, from the frames they sum.
        mean = np.stack([np.convolve(joined[:, e], kernel)[lead : lead + k] for e in range(2)], axis=1)
        self._vol = joined[-(n - 1) :].copy()
        b = DETECT_BATCH
        probs = np.concatenate([self.melcnn.detect(patches[i : i + b], mean[i : i + b]) for i in range(0, k, b)])
        probs = probs.astype(np.float32)
        self._max = probs.max(axis=0) if self._max is None else np.maximum(self._max, probs.max(axis=0))
        self.frames += k
        return frames.time_s, probs

    def overall(self) -> np.ndarray:
        """float32 (C,): the largest probability of each class over the frames so far."""
        if self._max is None:
            raise ConfigError("no frame was pushed")
        return self._max
