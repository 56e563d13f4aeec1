"""Realistic recorder input without running the auditory pipeline: for the benchmark, the
tests, and the README screenshot.

:func:`scene_model` gives the composed ``cabin`` or ``room`` scene (``world.scenes``), or,
where that module is not available, the cabin asset with the robot attached the same way
(``car/`` and ``robot/`` prefixes). :class:`SyntheticEpisode` produces, per ear frame, what an
episode hands to :meth:`Recorder.log_frame`, with the real shapes: percepts over the real
direction grid (a peaked existence map that follows a source), (2, 128) mel frames, audio
blocks of 705/706 samples on the sample clock, a turning head, joint motion (read by the
recorder through a :class:`~acoustic_sim.world.view.WorldView`), events, and eye-camera
images rendered by MuJoCo when an OpenGL backend is available.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import mujoco
import numpy as np

from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.auditory.percept import DirectionEstimate, Percept
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE, block_length, rotation_zyx, vec_to_sph
from acoustic_sim.world import actuation
from acoustic_sim.world.view import SceneView, WorldView

ASSETS = Path(__file__).resolve().parents[2] / "assets"
_GL_ERRORS = (mujoco.FatalError, RuntimeError, OSError, ImportError, AttributeError, ctypes.ArgumentError)


def scene_model(name: str = "cabin") -> tuple[mujoco.MjModel, str]:
    """The composed scene (``world.scenes.load_scene``) and where it came from; the cabin and
    robot assets attached by hand only where ``world.scenes`` cannot be imported."""
    try:
        from acoustic_sim.world.scenes import load_scene
    except ImportError:
        load_scene = None
    if load_scene is not None:
        return load_scene(name)[0], f"acoustic_sim.world.scenes.load_scene({name!r})"
    spec = mujoco.MjSpec()
    car = mujoco.MjSpec.from_file(str(ASSETS / "car_cabin" / "car_cabin.xml"))
    robot = mujoco.MjSpec.from_file(str(ASSETS / "musashi_head" / "musashi_head.xml"))
    spec.attach(car, prefix="car/", frame=spec.worldbody.add_frame())
    spec.attach(robot, prefix="robot/", frame=spec.worldbody.add_frame())
    return spec.compile(), "assets/car_cabin + assets/musashi_head (stand-in: world.scenes not available)"


def render_images(model: mujoco.MjModel, n: int, *, width: int = 320, height: int = 240) -> list[np.ndarray] | None:
    """``n`` eye-camera images (uint8 HxWx3) of the scene with the head turning, or None when
    no OpenGL backend works here."""
    cam = next((i for i in range(model.ncam) if "eye" in (model.cam(i).name or "")), 0 if model.ncam else -1)
    data = mujoco.MjData(model)
    view = SceneView(model, data)
    try:
        renderer = mujoco.Renderer(model, height, width)
    except _GL_ERRORS:  # no OpenGL backend here (MUJOCO_GL unset or unusable)
        return None
    yaw = _joint(model, "neck_yaw")
    images = []
    try:
        for k in range(n):
            if yaw is not None:
                actuation.set_joint_position(model, data, yaw, 0.8 * np.sin(2 * np.pi * k / max(n, 1)))
            actuation.forward(model, data)
            images.append(view.render(renderer, cam).copy())
    except _GL_ERRORS:
        return None
    finally:
        renderer.close()
    return images


def synthetic_images(n: int, *, width: int = 320, height: int = 240) -> list[np.ndarray]:
    """Smooth stand-in camera images (gradients and a moving blob), uint8 HxWx3."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    out = []
    for k in range(n):
        cx = width * (0.5 + 0.3 * np.sin(2 * np.pi * k / n))
        blob = np.exp(-((x - cx) ** 2 + (y - height / 2) ** 2) / (2 * 30.0**2))
        img = np.stack([120 + 80 * x / width, 90 + 60 * y / height + 100 * blob, 140 - 50 * blob], -1)
        out.append(np.clip(img, 0, 255).astype(np.uint8))
    return out


def _joint(model: mujoco.MjModel, suffix: str) -> int | None:
    for j in range(model.njnt):
        if (model.jnt(j).name or "").endswith(suffix):
            return j
    return None


class SyntheticEpisode:
    """Per-frame recorder input with the shapes of a real episode (deterministic for a seed).

    Parameters
    ----------
    model : mujoco.MjModel
    grid_vectors : numpy.ndarray
        (D, 3) head-frame unit vectors of the direction grid.
    seed : int
    camera : bool
        Produce eye-camera images (rendered if possible, else synthetic).
    n_images : int
        Distinct camera images, cycled.
    """

    def __init__(self, model: mujoco.MjModel, grid_vectors, *, seed: int = 0, camera: bool = True, n_images: int = 16) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.view = WorldView(model, self.data)
        self.grid = np.asarray(grid_vectors, dtype=np.float32)
        self.rng = np.random.default_rng(seed)
        self.images = None
        self.image_source = "none"
        if camera:
            self.images = render_images(model, n_images)
            self.image_source = "mujoco.Renderer (eye camera)"
            if self.images is None:
                self.images = synthetic_images(n_images)
                self.image_source = "synthetic (no OpenGL backend)"
        self.hinges = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
        self.head_pos = np.array([0.0, 0.0, 1.1])
        body = next((b for b in range(model.nbody) if (model.body(b).name or "").endswith("head")), None)
        if body is not None:
            actuation.kinematics(model, self.data)
            self.head_pos = self.view.body_poses()[0][body]
        self.sources = [
            ("dashboard alarm", "reverse_alarm", self.head_pos + [0.8, 0.0, 0.05]),
            ("radio", "human_voice", self.head_pos + [0.6, -0.4, 0.1]),
            ("other car", "reverse_alarm", self.head_pos + [-3.0, 1.5, 0.0]),
        ]
        self.noise = (0.02 * self.rng.standard_normal((2, SAMPLE_RATE))).astype(np.float32)
        self.tone = (0.05 * np.sin(2 * np.pi * 2500 * np.arange(SAMPLE_RATE) / SAMPLE_RATE)).astype(np.float32)
        self._sample = 0

    def frame(self, k: int) -> dict:
        """Keyword arguments of ``Recorder.log_frame`` for ear frame ``k`` (frames in order)."""
        t = (k + 1) / FRAME_RATE
        for i, j in enumerate(self.hinges):
            lo, hi = self.model.jnt_range[j] if self.model.jnt_limited[j] else (-0.5, 0.5)
            mid, amp = (lo + hi) / 2, (hi - lo) / 2 * 0.6
            actuation.set_joint_position(self.model, self.data, j, mid + amp * np.sin(2 * np.pi * t / (3.0 + 0.37 * i)))
        actuation.kinematics(self.model, self.data)
        yaw = 50.0 * np.sin(2 * np.pi * t / 4.0)
        rot = rotation_zyx(yaw)
        n = block_length(k)
        start = self._sample % (SAMPLE_RATE - 800)
        self._sample += n
        alarm_on = (t % 2.0) < 1.0
        block = self.noise[:, start:start + n] + (self.tone[start:start + n] if alarm_on else 0.0)
        # the alarm's head-frame direction, a peaked existence map around it, a little noise
        v = rot.T @ (self.sources[0][2] - self.head_pos)
        v = v / np.linalg.norm(v)
        existence = np.exp(8.0 * (self.grid @ v - 1.0)).astype(np.float32)
        existence += 0.05 * self.rng.random(existence.shape, dtype=np.float32)
        best = int(np.argmax(existence))
        az, el = vec_to_sph(self.grid[best])
        probs = (0.05 * self.rng.random(len(SOUND_CLASSES))).astype(np.float32)
        probs[SOUND_CLASSES.index("reverse_alarm")] = 0.95 if alarm_on else 0.1
        detected = ("reverse_alarm",) if alarm_on else ()
        directions = {}
        if alarm_on:
            directions["reverse_alarm"] = DirectionEstimate(
                vector=self.grid[best].astype(np.float64), azimuth_deg=float(az), elevation_deg=float(el),
                existence=existence, confidence=float((existence.max() - existence.mean()) / existence.max()), n_bins=40)
        mel = np.clip(-0.6 + 0.3 * self.rng.standard_normal((2, 128)), -1.0, 0.0).astype(np.float32)
        if alarm_on:
            mel[:, 70:74] = -0.02
        percept = Percept(frame=k, time_s=t, classes=SOUND_CLASSES, probabilities=probs, detected=detected,
                          directions=directions, mel=mel, volume=np.array([1.0, 0.9]))
        events = []
        if k % int(2 * FRAME_RATE) == 0:
            events.append(f"alarm started at {t:.2f} s")
        if k % 40 == 7:
            events.append("ratchet tooth clicked")
        return {
            "view": self.view, "sources": self.sources, "head_pose": (self.head_pos, rot), "percept": percept,
            "audio_block": block, "events": events,
            "camera_image": None if self.images is None else self.images[k % len(self.images)],
        }
