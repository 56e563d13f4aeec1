"""What the robot heard and perceived, in a recording: the true, estimated and tracked
directions as arrows from the head, the existence map on a sphere around it, the class
probabilities, the scrolling left/right mel spectrograms and the ears' waveform envelope.

:class:`HearingLog` is the part of :class:`~acoustic_sim.viz.recorder.Recorder` that draws
the hearing. To stay cheap the existence map is one uint16 class id per direction on static
points (logged only when it changes), arrows that did not move are skipped, and the
spectrograms are re-sent as a small JPEG every ``spectrogram_every`` frames.
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

from acoustic_sim.errors import ConfigError
from acoustic_sim.viz import blueprint as bp
from acoustic_sim.viz.recorder_config import RecorderConfig, RecordingError
from acoustic_sim.viz.rerun_rows import RowBuffer, jpeg, unchanged
from acoustic_sim.viz.style import TRUE_COLOR, class_color, colormap_lut


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64).reshape(3)
    n = math.sqrt(float(v @ v))
    return v / n if n > 0 else v


class HearingLog:
    """Logs the hearing of one recording into ``rows`` (sent when the recorder flushes).

    Parameters
    ----------
    rec, rows, config
        As for :class:`~acoustic_sim.viz.world_log.WorldLog` (the static parts are logged at once).
    classes : tuple of str
        Sound classes in the order of ``Percept.probabilities``.
    grid_vectors : numpy.ndarray or None
        (D, 3) head-frame unit vectors of the existence maps' direction grid; ``None``: no map.

    Raises
    ------
    ConfigError
        If ``grid_vectors`` is not a finite (D, 3) array.
    """

    def __init__(self, rec: rr.RecordingStream, rows: RowBuffer, config: RecorderConfig, classes: tuple[str, ...], *,
                 grid_vectors=None) -> None:
        self.rec = rec
        self.rows = rows
        self.config = config
        self.classes = classes
        self._lut = colormap_lut()
        self._class_rgb = {c: class_color(c, self.classes) for c in self.classes}
        self.grid: np.ndarray | None = None
        if grid_vectors is not None:
            self._log_grid(grid_vectors)
        self.rec.log(bp.PROBABILITIES, rr.SeriesLines(names=list(self.classes),
                                                       colors=[self._class_rgb[c] for c in self.classes]), static=True)
        # True arrows start where the labelled source points' directions are: their labels
        # (kept for hovering) would only repeat the sources' names on top of the estimate's.
        self.rec.log(bp.TRUE_DIRECTIONS, rr.Arrows3D.from_fields(show_labels=False), static=True)
        for path_, ear, rgb in ((bp.WAVEFORM_LEFT, "left", (31, 119, 180)), (bp.WAVEFORM_RIGHT, "right", (214, 39, 40))):
            self.rec.log(path_, rr.SeriesLines(names=[f"{ear} min", f"{ear} max"], colors=[rgb, rgb]), static=True)
        # change detection state
        self._last_true: tuple | None = None
        self._last_est: tuple | None = None
        self._last_tracked: tuple | None = None
        self._last_map: np.ndarray | None = None
        # spectrogram ring buffer: (W, 2, n_mels) uint8
        self._spec: np.ndarray | None = None
        self._spec_pos = 0
        self._spec_pushed = 0

    def _log_grid(self, grid_vectors) -> None:
        g = np.array(grid_vectors, dtype=np.float32)
        if g.ndim != 2 or g.shape[1] != 3 or g.shape[0] < 1 or not np.all(np.isfinite(g)):
            raise ConfigError(f"grid_vectors must be a finite (D, 3) array of head-frame unit vectors, got shape {g.shape}")
        self.grid = g
        levels = self.config.existence_levels
        lut = self._lut[np.linspace(0, 255, levels).round().astype(int)]
        self.rec.log(bp.EXISTENCE, rr.AnnotationContext([rr.AnnotationInfo(id=i, color=tuple(int(c) for c in lut[i]))
                                                          for i in range(levels)]), static=True)
        self.rec.log(bp.EXISTENCE, rr.Points3D(g * self.config.existence_radius_m, radii=0.008), static=True)

    def restart_spectrograms(self) -> None:
        """Start the scrolling spectrograms empty (a new episode)."""
        self._spec = None
        self._spec_pushed = 0

    # -- per frame -----------------------------------------------------------------------------

    def log_true(self, k: int, t: float, true_directions, sources, head) -> None:
        """The true directions: ``true_directions`` (label -> head-frame vector) if given,
        else those of ``sources`` (``(name, class, world position)``) seen from ``head``
        (position (3,), rotation (3, 3)); with neither, nothing."""
        if true_directions is not None:
            items = [(str(lbl), self._class_rgb.get(lbl, TRUE_COLOR), _unit(v)) for lbl, v in true_directions.items()]
        elif head is not None:
            pos, rot = head
            items = [(n, TRUE_COLOR, _unit(rot.T @ (p - pos))) for n, _c, p in sources]
        else:
            return
        self._log_arrows(bp.TRUE_DIRECTIONS, "_last_true", k, t, items)

    def _log_arrows(self, entity: str, last_attr: str, k: int, t: float, items) -> None:
        labels = tuple(lbl for lbl, _c, _v in items)
        vecs = np.array([v for *_x, v in items], dtype=np.float32).reshape(-1, 3) * self.config.arrow_length_m
        last = getattr(self, last_attr)
        if last is None and not items:
            return
        if unchanged(last, labels, vecs, self.config.pose_tolerance):
            return
        setattr(self, last_attr, (labels, vecs))
        colors = np.array([c for _l, c, _v in items], dtype=np.uint8).reshape(-1, 3)
        self.rows.rows(entity, rr.Arrows3D).add(k, t, len(items), vectors=vecs, colors=colors, labels=list(labels))

    def log_percept(self, k: int, t: float, percept) -> None:
        """A :class:`~acoustic_sim.auditory.percept.Percept`: probabilities, estimated and
        tracked directions, the existence map of the first estimate, and its mel frame."""
        classes = tuple(percept.classes)
        if classes != self.classes:
            raise RecordingError(f"percept classes {classes} differ from the recorder's {self.classes}")
        probs = np.asarray(percept.probabilities, dtype=np.float64).reshape(-1)
        self.rows.rows(bp.PROBABILITIES, rr.Scalars).add(k, t, probs.size, scalars=probs)
        items = []
        best = None
        for c in percept.detected:
            d = percept.directions.get(c)
            if d is None:
                continue
            if best is None:
                best = d
            items.append((f"{c} {percept.probability(c):.2f}", self._class_rgb.get(c, TRUE_COLOR), _unit(d.vector)))
        for c, d in percept.directions.items():  # estimates of classes not listed in detected
            if c not in percept.detected:
                items.append((c, self._class_rgb.get(c, TRUE_COLOR), _unit(d.vector)))
                best = best if best is not None else d
        self._log_arrows(bp.ESTIMATED_DIRECTIONS, "_last_est", k, t, items)
        tracked = [(f"{c} {'decided' if d.decided else 'front/back?'}", self._class_rgb.get(c, TRUE_COLOR),
                    _unit(d.head_vector)) for c, d in getattr(percept, "tracked", {}).items()]
        self._log_arrows(bp.TRACKED_DIRECTIONS, "_last_tracked", k, t, tracked)
        if self.grid is not None:
            self._log_map(k, t, best)
        if percept.mel is not None:
            self._push_mel(k, t, percept.mel)

    def _log_map(self, k: int, t: float, estimate) -> None:
        d = self.grid.shape[0]
        if estimate is None:
            ids = np.zeros(d, np.uint16)
        else:
            e = np.asarray(estimate.existence, dtype=np.float64).reshape(-1)
            if e.size != d:
                raise RecordingError(f"existence map has {e.size} directions, the recorder's grid has {d}")
            top = e.max()
            scale = (self.config.existence_levels - 1) / top if top > 0 else 0.0
            ids = np.clip(np.round(e * scale), 0, self.config.existence_levels - 1).astype(np.uint16)
        if self._last_map is not None and np.array_equal(ids, self._last_map):
            return
        if self._last_map is None and estimate is None:
            self._last_map = ids
            return
        self._last_map = ids
        self.rows.rows(bp.EXISTENCE, rr.Points3D).add(k, t, d, class_ids=ids)

    def _push_mel(self, k: int, t: float, mel) -> None:
        m = np.asarray(mel, dtype=np.float32)
        if m.ndim != 2 or m.shape[0] != 2:
            raise RecordingError(f"percept.mel must be (2, n_mels), got shape {m.shape}")
        lo, hi = self.config.mel_range
        col = np.clip((m - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)
        if self._spec is None or self._spec.shape[2] != m.shape[1]:
            self._spec = np.zeros((self.config.spectrogram_frames, 2, m.shape[1]), np.uint8)
            self._spec_pos = 0
        self._spec[self._spec_pos] = col
        self._spec_pos = (self._spec_pos + 1) % self._spec.shape[0]
        self._spec_pushed += 1
        if self._spec_pushed % self.config.spectrogram_every == 0:
            self._log_spectrograms(k, t)

    def _log_spectrograms(self, k: int, t: float) -> None:
        w = np.concatenate([self._spec[self._spec_pos:], self._spec[:self._spec_pos]])  # oldest first
        for ear, entity in ((0, bp.MEL_LEFT), (1, bp.MEL_RIGHT)):
            img = np.take(self._lut, w[:, ear, ::-1].T, axis=0)  # (n_mels, W, 3): time to the right, low pitch at the bottom
            self.rows.rows(entity, rr.EncodedImage).add(k, t, 1, blob=[jpeg(img, self.config.jpeg_quality)],
                                                        media_type=["image/jpeg"])

    def log_audio(self, k: int, t: float, block) -> None:
        """The waveform envelope of both ears' block (2, n): ``waveform_points`` min/max pairs
        per ear, time-stamped back from ``t`` (the block's end)."""
        x = np.asarray(block)
        if x.ndim != 2 or x.shape[0] != 2 or x.shape[1] < 1:
            raise RecordingError(f"audio_block must be (2, n) with n >= 1, got shape {x.shape}")
        n = x.shape[1]
        m = min(self.config.waveform_points, n)
        edges = (np.arange(m + 1) * n) // m
        lo = np.minimum.reduceat(x, edges[:-1], axis=1)
        hi = np.maximum.reduceat(x, edges[:-1], axis=1)
        times = t - (n - edges[1:]) / self.config.sample_rate
        times = times.tolist()
        pairs = np.stack([lo, hi], axis=-1).astype(np.float64)  # (ear, point, min/max)
        self.rows.rows(bp.WAVEFORM_LEFT, rr.Scalars).add_many(k, times, 2, scalars=pairs[0].ravel())
        self.rows.rows(bp.WAVEFORM_RIGHT, rr.Scalars).add_many(k, times, 2, scalars=pairs[1].ravel())
