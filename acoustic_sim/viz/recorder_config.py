"""The options of a recording (:class:`RecorderConfig`), its error type, and the check of
the path it is written to."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from acoustic_sim.errors import AcousticSimError, ConfigError
from acoustic_sim.frames import SAMPLE_RATE


class RecordingError(AcousticSimError):
    """A recording cannot be written or read (bad path, closed recorder, inconsistent input)."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class RecorderConfig:
    """Options of a :class:`Recorder`.

    Attributes
    ----------
    application_id : str
        Rerun application id (the viewer groups recordings by it).
    recording_id : str or None
        Rerun recording id; ``None`` lets rerun pick a UUID (not from the simulation's RNG).
    flush_every : int
        Frames buffered before they are sent (>= 1). A send costs about 0.3 ms per entity
        whatever its length, so 250 frames (4 s) keep that under 0.05 ms per frame; a live
        viewer lags by this much (use a small value when streaming to one).
    camera_every : int
        Log every k-th camera image given (>= 1); 4 is 15.6 images/s at 62.5 Hz.
    jpeg_quality : int
        JPEG quality of camera and spectrogram images, 1..95.
    spectrogram_frames : int
        Width of the scrolling spectrograms in ear frames (125 = 2 s).
    spectrogram_every : int
        Frames between two spectrogram images (>= 1); the picture scrolls in steps this wide.
    mel_range : tuple of float
        Values of ``Percept.mel`` mapped to the bottom and top of the colour map (the
        pipeline's normalised log-mel lies in [-1, 0]).
    waveform_points : int
        Min/max pairs per ear per frame in the waveform envelope (>= 1).
    sample_rate : int
        Sample rate of the audio blocks, Hz (for the envelope's time stamps).
    existence_radius_m : float
        Radius of the sphere of direction points around the head, metres.
    existence_levels : int
        Colour levels of the existence map, 2..256 (one uint16 class id per direction).
    arrow_length_m : float
        Length of the direction arrows, metres.
    geom_groups : tuple of int
        MuJoCo geom groups drawn (menagerie puts collision geoms in group 3).
    eye_aspect : float
        Width / height of the eye camera's frustum drawn in the 3D view (the env's images are 4:3).
    pose_tolerance : float
        A body pose, head pose or arrow that moved less than this (metres, or quaternion /
        unit-vector components) since it was last logged is not logged again.
    history_s : float
        Seconds of history in the blueprint's time-series views.
    play_state : str or None
        Where the viewer's time cursor starts: ``following`` (the newest data: a finished
        recording opens on its last frame), ``paused``, ``playing``, or ``None`` (rerun's default).
    """

    application_id: str = "acoustic_sim"
    recording_id: str | None = None
    flush_every: int = 250
    camera_every: int = 4
    jpeg_quality: int = 75
    spectrogram_frames: int = 125
    spectrogram_every: int = 8
    mel_range: tuple[float, float] = (-1.0, 0.0)
    waveform_points: int = 4
    sample_rate: int = SAMPLE_RATE
    existence_radius_m: float = 0.35
    existence_levels: int = 16
    arrow_length_m: float = 0.5
    geom_groups: tuple[int, ...] = (0, 1, 2)
    eye_aspect: float = 4.0 / 3.0
    pose_tolerance: float = 1e-5
    history_s: float = 10.0
    play_state: str | None = "following"

    def __post_init__(self) -> None:
        if not isinstance(self.application_id, str) or not self.application_id:
            raise ConfigError(f"RecorderConfig.application_id must be a non-empty string, got {self.application_id!r}")
        for name in ("flush_every", "camera_every", "spectrogram_frames", "spectrogram_every", "waveform_points", "sample_rate"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(f"RecorderConfig.{name} must be an integer >= 1, got {v!r}")
        if not 1 <= int(self.jpeg_quality) <= 95:
            raise ConfigError(f"RecorderConfig.jpeg_quality must be in 1..95, got {self.jpeg_quality!r}")
        if not 2 <= int(self.existence_levels) <= 256:
            raise ConfigError(f"RecorderConfig.existence_levels must be in 2..256, got {self.existence_levels!r}")
        lo, hi = self.mel_range
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(f"RecorderConfig.mel_range must be finite (low, high) with low < high, got {self.mel_range!r}")
        for name in ("existence_radius_m", "arrow_length_m", "history_s", "eye_aspect"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"RecorderConfig.{name} must be a positive number, got {v!r}")
        if self.play_state not in ("following", "paused", "playing", None):
            raise ConfigError(f"RecorderConfig.play_state must be 'following', 'paused', 'playing' or None, got {self.play_state!r}")
        if not (math.isfinite(self.pose_tolerance) and self.pose_tolerance >= 0):
            raise ConfigError(f"RecorderConfig.pose_tolerance must be >= 0, got {self.pose_tolerance!r}")


def prepare_path(path) -> Path:
    """Check that ``path`` can take a recording and create it (empty; parent folders too).

    Raises
    ------
    RecordingError
        If ``path`` does not end in ``.rrd``, is a folder, or cannot be written.
    """
    p = Path(path)
    if p.suffix.lower() != ".rrd":
        raise RecordingError(f"recording path must end in .rrd, got {str(p)!r}")
    if p.is_dir():
        raise RecordingError(f"recording path {str(p)!r} is a folder, expected an .rrd file path")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with open(p, "wb"):
            pass
    except OSError as err:
        raise RecordingError(f"cannot write recording {str(p)!r}: {err.strerror or err}") from err
    return p
