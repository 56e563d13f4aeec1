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

The recorder keeps the clock, the episode and the flushes; what is drawn lives in two parts
that share its row buffer (:mod:`~acoustic_sim.viz.rerun_rows`): the world
(:mod:`~acoustic_sim.viz.world_log`) and the hearing (:mod:`~acoustic_sim.viz.hearing_log`).
Its options and error type are in :mod:`~acoustic_sim.viz.recorder_config`.

Logging never changes the simulation: inputs are only read (the view hands out copies; the
recorder never sees ``MjData``), and no random number generator is used (rerun's recording id
is its own UUID).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Self

import mujoco
import numpy as np
import rerun as rr

from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.errors import ConfigError
from acoustic_sim.viz import blueprint as bp
from acoustic_sim.viz.hearing_log import HearingLog
from acoustic_sim.viz.recorder_config import RecorderConfig, RecordingError, prepare_path
from acoustic_sim.viz.rerun_rows import RowBuffer
from acoustic_sim.viz.scene_geometry import SceneGeometry, default_view
from acoustic_sim.viz.world_log import WorldLog


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
        self.episode: int | None = None
        """The current value of the ``episode`` timeline (``None`` until :meth:`set_episode`)."""
        self.frames_logged = 0
        self._closed = False
        self._pending = 0
        self._rows = RowBuffer()
        self.world = WorldLog(stream, self._rows, self.config, self.classes, model=model, eye_camera=eye_camera)
        """The scene, the bodies, the head, the eye camera and the sources."""
        self.hearing = HearingLog(stream, self._rows, self.config, self.classes, grid_vectors=grid_vectors)
        """The directions, the existence map, the probabilities, the spectrograms and the waveform."""

    @property
    def geometry(self) -> SceneGeometry | None:
        """The scene's geometry (``None`` without a model)."""
        return self.world.geometry

    @property
    def grid(self) -> np.ndarray | None:
        """The direction grid's (D, 3) float32 vectors (``None`` without one)."""
        return self.hearing.grid

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

    # -- per frame -----------------------------------------------------------------------------

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
        self.hearing.restart_spectrograms()

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
            self.world.log_view(k, t, view)
        head = None
        if head_pose is not None:
            head = (np.asarray(head_pose[0], dtype=np.float64).reshape(3),
                    np.asarray(head_pose[1], dtype=np.float64).reshape(3, 3))
            self.world.log_head(k, t, *head)
        srcs = [(str(n), str(c), np.asarray(p, dtype=np.float64).reshape(3)) for n, c, p in sources]
        self.world.log_sources(k, t, srcs)
        self.hearing.log_true(k, t, true_directions, srcs, head)
        if percept is not None:
            self.hearing.log_percept(k, t, percept)
        if audio_block is not None:
            self.hearing.log_audio(k, t, audio_block)
        ev = [_event_text(e) for e in events]
        if ev:
            self._rows.rows(bp.EVENTS, rr.TextLog).add(k, t, len(ev), text=ev, level=["INFO"] * len(ev))
        if camera_image is not None:
            self.world.log_camera(k, t, camera_image)

        self.frames_logged += 1
        self._pending += 1
        if self._pending >= self.config.flush_every:
            self.flush()

    # -- output --------------------------------------------------------------------------------

    def flush(self) -> None:
        """Send everything buffered (called every ``flush_every`` frames and on close)."""
        self.world.send_bodies(self.episode)
        self._rows.send(self.rec, self.episode)
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
