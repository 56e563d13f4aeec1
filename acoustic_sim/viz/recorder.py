"""Rerun recordings of an episode: the scene, what the ears heard, what the robot perceived.

One :class:`Recorder` writes one ``.rrd`` file. It logs the MuJoCo geoms once (static), then,
per ear frame, what :meth:`Recorder.log_frame` is given: body poses (read through the world's
``WorldView.body_poses()``), the eye camera's frustum (``WorldView.camera_pose``), sound
sources, the true and estimated directions as arrows from the head, the existence map on a
sphere around the head, scrolling left/right mel spectrograms, class probabilities, the ears'
waveform envelope, events, and the eye camera image. Time runs on two timelines: ``sim_time``
(seconds) and ``frame`` (the ear-frame sequence); after :meth:`Recorder.set_episode`, a third,
``episode``, numbers the episodes of a recording that holds several
(:class:`acoustic_sim.viz.episode.EpisodeRecorder` lays them out one after another).

Cost. ``rr.log`` costs 70-250 us a call, so per-frame data is not logged row by row: it is
buffered in numpy and sent with ``send_columns`` every ``flush_every`` frames (one call per
entity), rows whose value did not change (a resting lever, a silent map) are skipped, images
are JPEG (uint8), the existence map is one uint16 class id per direction on static points, and
the spectrograms are re-sent as a small JPEG every ``spectrogram_every`` frames. The price is
that a live viewer sees data up to ``flush_every`` frames late; a file is complete on
:meth:`Recorder.close`. ``benchmarks/bench_viz.py`` measures ms per frame and MB per minute.

Logging never changes the simulation: inputs are only read (the view hands out copies; the
recorder never sees ``MjData``), and no random number generator is used (rerun's recording id
is its own UUID).
"""

from __future__ import annotations

import dataclasses
import io
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Self

import mujoco
import numpy as np
import rerun as rr
from PIL import Image

from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.errors import AcousticSimError, ConfigError
from acoustic_sim.frames import SAMPLE_RATE
from acoustic_sim.viz import blueprint as bp
from acoustic_sim.viz.scene_geometry import SceneGeometry, default_view
from acoustic_sim.viz.style import TRUE_COLOR, class_color, colormap_lut


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


class _Rows:
    """Rows of one entity waiting to be sent: time stamps and per-row component batches."""

    __slots__ = ("archetype", "cols", "frames", "lengths", "times")

    def __init__(self, archetype) -> None:
        self.archetype = archetype
        self.frames: list[int] = []
        self.times: list[float] = []
        self.lengths: list[int] = []
        self.cols: dict[str, list] = {}

    def add(self, frame: int, t: float, n: int, **cols) -> None:
        self.frames.append(frame)
        self.times.append(t)
        self.lengths.append(n)
        for k, v in cols.items():
            self.cols.setdefault(k, []).append(v)

    def add_many(self, frame: int, times, n: int, **cols) -> None:
        """Rows of one frame at several times, each of ``n`` instances (arrays concatenated)."""
        m = len(times)
        self.frames.extend([frame] * m)
        self.times.extend(times)
        self.lengths.extend([n] * m)
        for k, v in cols.items():
            self.cols.setdefault(k, []).append(v)

    def send(self, rec: rr.RecordingStream, entity: str, episode: int | None = None) -> None:
        """Send the rows (one ``send_columns`` call); ``episode``: the value of the ``episode``
        timeline for all of them (the recorder flushes before the episode changes)."""
        if not self.frames:
            return
        cols = {}
        for k, v in self.cols.items():
            if isinstance(v[0], np.ndarray):
                cols[k] = np.concatenate(v)
            else:
                cols[k] = [x for part in v for x in part]
        columns = self.archetype.columns(**cols).partition(self.lengths)
        rec.send_columns(entity, indexes=_indexes(self.frames, self.times, episode), columns=columns)
        self.frames, self.times, self.lengths, self.cols = [], [], [], {}


def _indexes(frames, times, episode: int | None) -> list[rr.TimeColumn]:
    """The time columns of a batch of rows: ``frame``, ``sim_time`` and, if set, ``episode``."""
    frames = np.asarray(frames, np.int64)
    cols = [rr.TimeColumn(bp.FRAME_TIMELINE, sequence=frames),
            rr.TimeColumn(bp.TIMELINE, duration=np.asarray(times, np.float64))]
    if episode is not None:
        cols.append(rr.TimeColumn(bp.EPISODE_TIMELINE, sequence=np.full(frames.size, episode, np.int64)))
    return cols


def _jpeg(image: np.ndarray, quality: int) -> bytes:
    out = io.BytesIO()
    Image.fromarray(image).save(out, format="JPEG", quality=quality)
    return out.getvalue()


def _event_text(event) -> str:
    """A line for the event log: strings as they are, ``world.events.SoundEvent`` s spelled out."""
    if isinstance(event, str):
        return event
    kind = getattr(event, "kind", None)
    if kind is None:
        return str(event)
    text = f"{kind}: {getattr(event, 'label', '')} from {getattr(event, 'source', '?')}"
    detail = getattr(event, "detail", "")
    return f"{text} ({detail})" if detail else text


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64).reshape(3)
    n = math.sqrt(float(v @ v))
    return v / n if n > 0 else v


class Recorder:
    """Writes one episode to a rerun recording. Build it with :meth:`open`.

    Parameters
    ----------
    stream : rerun.RecordingStream
        An open stream with its sink set (a file for :meth:`open`).
    model : mujoco.MjModel or None
        The scene; its geoms are logged once. ``None``: no scene.
    grid_vectors : numpy.ndarray or None
        (D, 3) unit vectors, head frame, of the direction grid the percept's existence maps
        are over (``DirectionGrid.paper(HRTF.load("kemar")).vectors``). ``None``: no map.
    classes : tuple of str
        Sound classes in the order of ``Percept.probabilities``.
    config : RecorderConfig
    path : pathlib.Path or None
        The file the stream writes to (for messages).
    eye_camera : str or None
        Full name of a camera of ``model`` (``robot/eye_right``): its frustum is drawn in the
        3D view at the pose ``view.camera_pose(eye_camera)`` of every frame. ``None``: none.

    Raises
    ------
    ConfigError
        If ``classes`` is empty, ``grid_vectors`` is not (D, 3), or ``eye_camera`` is given
        without a model or is not a camera of it.
    """

    def __init__(self, stream: rr.RecordingStream, *, model: mujoco.MjModel | None = None,
                 grid_vectors=None, classes: Sequence[str] = SOUND_CLASSES,
                 config: RecorderConfig | None = None, path: Path | None = None,
                 eye_camera: str | None = None) -> None:
        self.config = config if config is not None else RecorderConfig()
        self.rec = stream
        self.path = path
        self.classes = tuple(classes)
        if not self.classes or not all(isinstance(c, str) and c for c in self.classes):
            raise ConfigError(f"classes must be a non-empty sequence of class names, got {classes!r}")
        self.eye_camera = eye_camera
        if eye_camera is not None:
            if model is None:
                raise ConfigError(f"eye_camera {eye_camera!r} needs the model it belongs to")
            cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, eye_camera)
            if cid < 0:
                raise ConfigError(f"eye_camera {eye_camera!r} is not a camera of the model")
            self._eye_fovy_rad = math.radians(float(model.cam_fovy[cid]))
        self.episode: int | None = None
        """The current value of the ``episode`` timeline (``None`` until :meth:`set_episode`)."""
        self.frames_logged = 0
        self._closed = False
        self._pending = 0
        self._rows: dict[str, _Rows] = {}
        self._lut = colormap_lut()
        self._class_rgb = {c: class_color(c, self.classes) for c in self.classes}

        self.rec.log(bp.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self.geometry = None
        if model is not None:
            self._log_scene(model)
        if eye_camera is not None:
            # MuJoCo's cameras look along -z with +y up: rerun's RUB.
            self.rec.log(bp.EYE_FRUSTUM, rr.Pinhole(fov_y=self._eye_fovy_rad, aspect_ratio=self.config.eye_aspect,
                                                    camera_xyz=rr.ViewCoordinates.RUB, image_plane_distance=0.12),
                         static=True)
        self.grid = None
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
        self._last_head: np.ndarray | None = None
        self._last_eye: np.ndarray | None = None
        self._last_sources: tuple | None = None
        self._last_true: tuple | None = None
        self._last_est: tuple | None = None
        self._last_tracked: tuple | None = None
        self._last_map: np.ndarray | None = None
        self._camera_seen = 0
        # spectrogram ring buffer: (W, 2, n_mels) uint8
        self._spec: np.ndarray | None = None
        self._spec_pos = 0
        self._spec_pushed = 0

    # -- construction --------------------------------------------------------------------------

    @classmethod
    def open(cls, path, model: mujoco.MjModel | None = None, grid_vectors=None,
             classes: Sequence[str] = SOUND_CLASSES, *, config: RecorderConfig | None = None,
             eye_camera: str | None = None, name: str | None = None) -> Recorder:
        """Start a recording written to ``path`` (an ``.rrd`` file; parent folders are created).

        Parameters
        ----------
        path : str or pathlib.Path
            The file; an existing one is overwritten.
        model, grid_vectors, classes, config, eye_camera
            As for :class:`Recorder`.
        name : str or None
            The recording's name in the viewer; default the file's stem.

        Raises
        ------
        RecordingError
            If ``path`` does not end in ``.rrd``, is a folder, or cannot be written.
        """
        cfg = config if config is not None else RecorderConfig()
        p = prepare_path(path)
        target, eye = default_view(model) if model is not None else (None, None)
        stream = rr.RecordingStream(cfg.application_id, recording_id=cfg.recording_id)
        stream.save(p, default_blueprint=bp.default_blueprint(
            history_s=cfg.history_s, look_target=target, eye_position=eye, play_state=cfg.play_state))
        stream.send_recording_name(name or p.stem)
        try:
            return cls(stream, model=model, grid_vectors=grid_vectors, classes=classes, config=cfg, path=p,
                       eye_camera=eye_camera)
        except BaseException:
            stream.disconnect()
            raise

    def _log_scene(self, model: mujoco.MjModel) -> None:
        self.geometry = geo = SceneGeometry(model, root=bp.WORLD, geom_groups=self.config.geom_groups)
        for shape in geo.shapes():
            self.rec.log(shape.entity, rr.Transform3D(translation=shape.translation, quaternion=shape.quaternion_xyzw),
                         shape.archetype, static=True)
        n = len(geo.body_paths)
        self._body_t = np.full((n, 3), np.nan, np.float32)
        self._body_q = np.full((n, 4), np.nan, np.float32)
        self._body_rows: list[tuple] = []  # (frame, time, body indices, translations, quaternions)

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

    # -- per frame -----------------------------------------------------------------------------

    def _rows_for(self, entity: str, archetype) -> _Rows:
        rows = self._rows.get(entity)
        if rows is None:
            rows = self._rows[entity] = _Rows(archetype)
        return rows

    def set_episode(self, episode: int) -> None:
        """Rows logged from now on carry ``episode`` on the ``episode`` timeline.

        What is buffered is sent first (a batch holds one episode), and the scrolling
        spectrograms start empty, so that an episode's picture holds none of the previous one.

        Parameters
        ----------
        episode : int
            Episode number, >= 0.

        Raises
        ------
        RecordingError
            If the recorder is closed or ``episode`` is not an integer >= 0.
        """
        if self._closed:
            raise RecordingError("set_episode() on a closed Recorder")
        if isinstance(episode, bool) or not isinstance(episode, (int, np.integer)) or episode < 0:
            raise RecordingError(f"episode must be an integer >= 0, got {episode!r}")
        self.flush()
        self.episode = int(episode)
        self._spec = None
        self._spec_pushed = 0

    def log_frame(self, time_s: float, frame: int, *, view=None,
                  sources: Iterable[tuple[str, str, object]] = (),
                  head_pose: tuple[object, object] | None = None,
                  true_directions: Mapping[str, object] | None = None,
                  percept=None, audio_block=None, events: Iterable[str] = (),
                  camera_image=None) -> None:
        """Log one ear frame. Every argument but the times is optional; inputs are only read.

        Parameters
        ----------
        time_s : float
            Simulation time in seconds (the ``sim_time`` timeline): the end of the ear frame.
        frame : int
            Ear frame number (the ``frame`` timeline), >= 0.
        view : acoustic_sim.world.view.WorldView, optional
            The world of the model given to :meth:`open`: body poses are read with
            ``view.body_poses()`` (copies of ``xpos``/``xquat``) and, if the recorder has an
            ``eye_camera``, its pose with ``view.camera_pose(eye_camera)``. Any object with
            those methods will do.
        sources : iterable of (name, class, world position)
            The active sound sources; each is drawn as a point labelled ``name`` coloured by class.
        head_pose : (position (3,), rotation (3, 3)), optional
            The head frame in the world (columns of the rotation are the head's x, y, z axes).
            Needed for the arrows and the existence map.
        true_directions : mapping of label to (3,) unit vector, optional
            True directions in the head frame. If ``None``, they are derived from ``sources``
            and ``head_pose`` (one per source).
        percept : acoustic_sim.auditory.percept.Percept, optional
            Probabilities, estimated directions, existence map and mel frame.
        audio_block : array (2, n), optional
            The block of both ears for this frame (left, right), any unit.
        events : iterable of str or ``world.events.SoundEvent``
            Events of this frame (``"hand released"``, ``"person in view"``, sound events ...),
            one line each in the event log.
        camera_image : uint8 array (H, W, 3), (H, W, 4) or (H, W), optional
            Eye camera image; every ``camera_every``-th one given is logged as JPEG.
        """
        if self._closed:
            raise RecordingError("log_frame() on a closed Recorder")
        t = float(time_s)
        if not math.isfinite(t):
            raise RecordingError(f"time_s must be finite, got {time_s!r}")
        if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or frame < 0:
            raise RecordingError(f"frame must be an integer >= 0, got {frame!r}")
        k = int(frame)

        if view is not None:
            if self.geometry is not None:
                self._log_bodies(k, t, view)
            if self.eye_camera is not None:
                self._log_eye(k, t, view)
        rot = None
        if head_pose is not None:
            pos = np.asarray(head_pose[0], dtype=np.float64).reshape(3)
            rot = np.asarray(head_pose[1], dtype=np.float64).reshape(3, 3)
            self._log_head(k, t, pos, rot)
        srcs = [(str(n), str(c), np.asarray(p, dtype=np.float64).reshape(3)) for n, c, p in sources]
        self._log_sources(k, t, srcs)
        if true_directions is not None:
            true = [(str(lbl), self._class_rgb.get(lbl, TRUE_COLOR), _unit(v)) for lbl, v in true_directions.items()]
            self._log_true(k, t, true)
        elif rot is not None:
            true = [(n, TRUE_COLOR, _unit(rot.T @ (p - pos))) for n, _c, p in srcs]
            self._log_true(k, t, true)
        if percept is not None:
            self._log_percept(k, t, percept)
        if audio_block is not None:
            self._log_audio(k, t, audio_block)
        ev = [_event_text(e) for e in events]
        if ev:
            self._rows_for(bp.EVENTS, rr.TextLog).add(k, t, len(ev), text=ev, level=["INFO"] * len(ev))
        if camera_image is not None:
            self._log_camera(k, t, camera_image)

        self.frames_logged += 1
        self._pending += 1
        if self._pending >= self.config.flush_every:
            self.flush()

    def _log_bodies(self, k: int, t: float, view) -> None:
        xpos, xquat = view.body_poses()
        try:
            trans, quat = self.geometry.body_poses(xpos, xquat)
        except ValueError as err:
            raise RecordingError(f"view.body_poses() does not fit the recorder's model: {err}") from err
        tol = self.config.pose_tolerance
        changed = ~((np.abs(trans - self._body_t) <= tol).all(axis=1) & (np.abs(quat - self._body_q) <= tol).all(axis=1))
        changed[0] = False  # the world body is the identity
        idx = np.flatnonzero(changed)
        if idx.size:
            self._body_t[idx] = trans[idx]
            self._body_q[idx] = quat[idx]
            self._body_rows.append((k, t, idx, trans[idx], quat[idx]))

    def _log_eye(self, k: int, t: float, view) -> None:
        pos, rot = view.camera_pose(self.eye_camera)
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot, dtype=np.float64).ravel())
        pose = np.concatenate([np.asarray(pos, np.float64).reshape(3), q[[1, 2, 3, 0]]]).astype(np.float32)
        if self._last_eye is not None and np.all(np.abs(pose - self._last_eye) <= self.config.pose_tolerance):
            return
        self._last_eye = pose
        self._rows_for(bp.EYE_FRUSTUM, rr.Transform3D).add(k, t, 1, translation=pose[None, :3], quaternion=pose[None, 3:])

    def _log_head(self, k: int, t: float, pos: np.ndarray, rot: np.ndarray) -> None:
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot).ravel())
        pose = np.concatenate([pos, q[[1, 2, 3, 0]]]).astype(np.float32)
        if self._last_head is not None and np.all(np.abs(pose - self._last_head) <= self.config.pose_tolerance):
            return
        self._last_head = pose
        self._rows_for(bp.HEARING, rr.Transform3D).add(k, t, 1, translation=pose[None, :3], quaternion=pose[None, 3:])

    def _same(self, last, labels, vecs) -> bool:
        return (last is not None and last[0] == labels and last[1].shape == vecs.shape
                and bool(np.all(np.abs(last[1] - vecs) <= self.config.pose_tolerance)))

    def _log_sources(self, k: int, t: float, srcs) -> None:
        labels = tuple((n, c) for n, c, _p in srcs)
        pos = np.array([p for *_x, p in srcs], dtype=np.float32).reshape(-1, 3)
        if self._last_sources is None and not srcs:
            return
        if self._same(self._last_sources, labels, pos):
            return
        self._last_sources = (labels, pos)
        colors = np.array([class_color(c, self.classes) for _n, c in labels], dtype=np.uint8).reshape(-1, 3)
        self._rows_for(bp.SOURCES, rr.Points3D).add(k, t, len(srcs), positions=pos, colors=colors,
                                                     labels=[n for n, _c in labels], radii=np.full(len(srcs), 0.03, np.float32))

    def _log_arrows(self, entity: str, last_attr: str, k: int, t: float, items) -> None:
        labels = tuple(lbl for lbl, _c, _v in items)
        vecs = np.array([v for *_x, v in items], dtype=np.float32).reshape(-1, 3) * self.config.arrow_length_m
        last = getattr(self, last_attr)
        if last is None and not items:
            return
        if self._same(last, labels, vecs):
            return
        setattr(self, last_attr, (labels, vecs))
        colors = np.array([c for _l, c, _v in items], dtype=np.uint8).reshape(-1, 3)
        self._rows_for(entity, rr.Arrows3D).add(k, t, len(items), vectors=vecs, colors=colors, labels=list(labels))

    def _log_true(self, k: int, t: float, items) -> None:
        self._log_arrows(bp.TRUE_DIRECTIONS, "_last_true", k, t, items)

    def _log_percept(self, k: int, t: float, percept) -> None:
        classes = tuple(percept.classes)
        if classes != self.classes:
            raise RecordingError(f"percept classes {classes} differ from the recorder's {self.classes}")
        probs = np.asarray(percept.probabilities, dtype=np.float64).reshape(-1)
        self._rows_for(bp.PROBABILITIES, rr.Scalars).add(k, t, probs.size, scalars=probs)
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
        self._rows_for(bp.EXISTENCE, rr.Points3D).add(k, t, d, class_ids=ids)

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
            self._rows_for(entity, rr.EncodedImage).add(k, t, 1, blob=[_jpeg(img, self.config.jpeg_quality)],
                                                        media_type=["image/jpeg"])

    def _log_audio(self, k: int, t: float, block) -> None:
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
        self._rows_for(bp.WAVEFORM_LEFT, rr.Scalars).add_many(k, times, 2, scalars=pairs[0].ravel())
        self._rows_for(bp.WAVEFORM_RIGHT, rr.Scalars).add_many(k, times, 2, scalars=pairs[1].ravel())

    def _log_camera(self, k: int, t: float, image) -> None:
        img = np.asarray(image)
        if img.dtype != np.uint8 or not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] in (3, 4))):
            raise RecordingError(f"camera_image must be uint8 (H, W), (H, W, 3) or (H, W, 4), got {img.dtype} {img.shape}")
        self._camera_seen += 1
        if (self._camera_seen - 1) % self.config.camera_every:
            return
        if img.ndim == 3 and img.shape[2] == 4:
            img = img[:, :, :3]
        self._rows_for(bp.CAMERA, rr.EncodedImage).add(k, t, 1, blob=[_jpeg(np.ascontiguousarray(img), self.config.jpeg_quality)],
                                                       media_type=["image/jpeg"])

    # -- output --------------------------------------------------------------------------------

    def flush(self) -> None:
        """Send everything buffered (called every ``flush_every`` frames and on close)."""
        if self.geometry is not None and self._body_rows:
            frames = np.concatenate([np.full(len(r[2]), r[0], np.int64) for r in self._body_rows])
            times = np.concatenate([np.full(len(r[2]), r[1], np.float64) for r in self._body_rows])
            body = np.concatenate([r[2] for r in self._body_rows])
            trans = np.concatenate([r[3] for r in self._body_rows])
            quat = np.concatenate([r[4] for r in self._body_rows])
            self._body_rows = []
            order = np.argsort(body, kind="stable")
            body, frames, times, trans, quat = body[order], frames[order], times[order], trans[order], quat[order]
            starts = np.flatnonzero(np.r_[True, body[1:] != body[:-1]])
            ends = np.r_[starts[1:], body.size]
            for s, e in zip(starts, ends):
                self.rec.send_columns(
                    self.geometry.body_paths[body[s]],
                    indexes=_indexes(frames[s:e], times[s:e], self.episode),
                    columns=rr.Transform3D.columns(translation=trans[s:e], quaternion=quat[s:e]),
                )
        for entity, rows in self._rows.items():
            rows.send(self.rec, entity, self.episode)
        self._pending = 0

    def close(self) -> None:
        """Send what is buffered and close the file. Safe to call twice."""
        if self._closed:
            return
        try:
            self.flush()
            self.rec.flush()
        finally:
            self._closed = True
            self.rec.disconnect()

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
