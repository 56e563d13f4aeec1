"""The world in a recording: the scene's geoms, the bodies' poses, the head, the eye camera
(its frustum and its images) and the sound sources.

:class:`WorldLog` is the part of :class:`~acoustic_sim.viz.recorder.Recorder` that draws the
world. The MuJoCo geoms are logged once (static); per frame, a body, the head or the eye
whose pose moved less than ``RecorderConfig.pose_tolerance`` since it was last logged, or
sources that did not move, are not logged again. Poses are only read (the world's
``WorldView`` hands out copies; this code never sees ``MjData``).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import rerun as rr

from acoustic_sim.errors import ConfigError
from acoustic_sim.viz import blueprint as bp
from acoustic_sim.viz.recorder_config import RecorderConfig, RecordingError
from acoustic_sim.viz.rerun_rows import RowBuffer, jpeg, time_indexes, unchanged
from acoustic_sim.viz.scene_geometry import SceneGeometry
from acoustic_sim.viz.style import class_color


def _pose(pos, rot) -> np.ndarray:
    """(7,) float32: the translation and the quaternion (x, y, z, w) of a position (3,) and a
    rotation matrix (3, 3)."""
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rot, dtype=np.float64).ravel())
    return np.concatenate([np.asarray(pos, np.float64).reshape(3), q[[1, 2, 3, 0]]]).astype(np.float32)


class WorldLog:
    """Logs the world of one recording into ``rows`` (sent when the recorder flushes).

    Parameters
    ----------
    rec : rerun.RecordingStream
        The recording (the static scene is logged to it at once).
    rows : RowBuffer
        Where per-frame rows wait for the recorder's flush.
    config : RecorderConfig
    classes : tuple of str
        Sound classes (a source's colour is its class's).
    model : mujoco.MjModel or None
        The scene; ``None``: no scene.
    eye_camera : str or None
        Full name of a camera of ``model`` whose frustum is drawn; ``None``: none.

    Raises
    ------
    ConfigError
        If ``eye_camera`` is given without a model or is not a camera of it.
    """

    def __init__(self, rec: rr.RecordingStream, rows: RowBuffer, config: RecorderConfig, classes: tuple[str, ...], *,
                 model: mujoco.MjModel | None = None, eye_camera: str | None = None) -> None:
        self.rec = rec
        self.rows = rows
        self.config = config
        self.classes = classes
        self.eye_camera = eye_camera
        if eye_camera is not None:
            if model is None:
                raise ConfigError(f"eye_camera {eye_camera!r} needs the model it belongs to")
            cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, eye_camera)
            if cid < 0:
                raise ConfigError(f"eye_camera {eye_camera!r} is not a camera of the model")
            self._eye_fovy_rad = math.radians(float(model.cam_fovy[cid]))

        self.rec.log(bp.WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self.geometry: SceneGeometry | None = None
        if model is not None:
            self._log_scene(model)
        if eye_camera is not None:
            # MuJoCo's cameras look along -z with +y up: rerun's RUB.
            self.rec.log(bp.EYE_FRUSTUM, rr.Pinhole(fov_y=self._eye_fovy_rad, aspect_ratio=self.config.eye_aspect,
                                                    camera_xyz=rr.ViewCoordinates.RUB, image_plane_distance=0.12),
                         static=True)
        # change detection state
        self._last_head: np.ndarray | None = None
        self._last_eye: np.ndarray | None = None
        self._last_sources: tuple | None = None
        self._camera_seen = 0

    def _log_scene(self, model: mujoco.MjModel) -> None:
        self.geometry = geo = SceneGeometry(model, root=bp.WORLD, geom_groups=self.config.geom_groups)
        for shape in geo.shapes():
            self.rec.log(shape.entity, rr.Transform3D(translation=shape.translation, quaternion=shape.quaternion_xyzw),
                         shape.archetype, static=True)
        n = len(geo.body_paths)
        self._body_t = np.full((n, 3), np.nan, np.float32)
        self._body_q = np.full((n, 4), np.nan, np.float32)
        self._body_rows: list[tuple] = []  # (frame, time, body indices, translations, quaternions)

    # -- per frame -----------------------------------------------------------------------------

    def log_view(self, k: int, t: float, view) -> None:
        """The bodies' poses (``view.body_poses()``, with a scene) and the eye camera's
        (``view.camera_pose``, with an ``eye_camera``) at frame ``k``, time ``t`` (s)."""
        if self.geometry is not None:
            self._log_bodies(k, t, view)
        if self.eye_camera is not None:
            self._log_pose(bp.EYE_FRUSTUM, "_last_eye", k, t, _pose(*view.camera_pose(self.eye_camera)))

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

    def log_head(self, k: int, t: float, pos: np.ndarray, rot: np.ndarray) -> None:
        """The head frame's pose: position (3,) and rotation (3, 3), world frame."""
        self._log_pose(bp.HEARING, "_last_head", k, t, _pose(pos, rot))

    def _log_pose(self, entity: str, last_attr: str, k: int, t: float, pose: np.ndarray) -> None:
        last = getattr(self, last_attr)
        if last is not None and np.all(np.abs(pose - last) <= self.config.pose_tolerance):
            return
        setattr(self, last_attr, pose)
        self.rows.rows(entity, rr.Transform3D).add(k, t, 1, translation=pose[None, :3], quaternion=pose[None, 3:])

    def log_sources(self, k: int, t: float, srcs) -> None:
        """The sound sources: ``(name, class, world position (3,))`` each, a point labelled
        by name and coloured by class."""
        labels = tuple((n, c) for n, c, _p in srcs)
        pos = np.array([p for *_x, p in srcs], dtype=np.float32).reshape(-1, 3)
        if self._last_sources is None and not srcs:
            return
        if unchanged(self._last_sources, labels, pos, self.config.pose_tolerance):
            return
        self._last_sources = (labels, pos)
        colors = np.array([class_color(c, self.classes) for _n, c in labels], dtype=np.uint8).reshape(-1, 3)
        self.rows.rows(bp.SOURCES, rr.Points3D).add(k, t, len(srcs), positions=pos, colors=colors,
                                                     labels=[n for n, _c in labels], radii=np.full(len(srcs), 0.03, np.float32))

    def log_camera(self, k: int, t: float, image) -> None:
        """An eye camera image, uint8 (H, W), (H, W, 3) or (H, W, 4): every ``camera_every``-th
        one given is logged as JPEG."""
        img = np.asarray(image)
        if img.dtype != np.uint8 or not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] in (3, 4))):
            raise RecordingError(f"camera_image must be uint8 (H, W), (H, W, 3) or (H, W, 4), got {img.dtype} {img.shape}")
        self._camera_seen += 1
        if (self._camera_seen - 1) % self.config.camera_every:
            return
        if img.ndim == 3 and img.shape[2] == 4:
            img = img[:, :, :3]
        self.rows.rows(bp.CAMERA, rr.EncodedImage).add(k, t, 1, blob=[jpeg(np.ascontiguousarray(img), self.config.jpeg_quality)],
                                                       media_type=["image/jpeg"])

    # -- output --------------------------------------------------------------------------------

    def send_bodies(self, episode: int | None) -> None:
        """Send the buffered body poses: one ``send_columns`` call per body that moved."""
        if self.geometry is None or not self._body_rows:
            return
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
                indexes=time_indexes(frames[s:e], times[s:e], episode),
                columns=rr.Transform3D.columns(translation=trans[s:e], quaternion=quat[s:e]),
            )
