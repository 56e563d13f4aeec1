"""The task envs' pictures: the scene from its fixed camera and what the right eye sees.

Two offscreen MuJoCo renderers, each built on first use and kept for the episode (a new
episode's model needs new ones: :meth:`tasks.base.HearingTaskEnv.reset` starts a new
:class:`Pictures`). Sites are hidden in both; the scene's picture also hides the geoms of
:data:`~acoustic_sim.world.snapshot.HIDDEN_GEOM_GROUP`.
"""

from __future__ import annotations

import mujoco
import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.world import names
from acoustic_sim.world.snapshot import HIDDEN_GEOM_GROUP, VIEWS
from acoustic_sim.world.view import SceneView


class Pictures:
    """The scene's and the eye's renderers of one episode (none built until asked for)."""

    def __init__(self) -> None:
        self._scene_renderer = None
        self._eye_renderer = None

    def scene(self, model: mujoco.MjModel, data: mujoco.MjData, scene_name: str, view) -> np.ndarray:
        """A 480 x 640 RGB picture of the scene from its fixed camera (:data:`VIEWS`); the
        room's follows the wheelchair (``view``: the episode's
        :class:`~acoustic_sim.world.view.WorldView`)."""
        if self._scene_renderer is None:
            self._scene_renderer = offscreen(model, 480, 640)
            cam = mujoco.MjvCamera()
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE
            fixed = VIEWS[scene_name]
            cam.lookat[:] = fixed.lookat
            cam.distance, cam.azimuth, cam.elevation = fixed.distance, fixed.azimuth, fixed.elevation
            opt = mujoco.MjvOption()
            opt.sitegroup[:] = 0
            opt.geomgroup[HIDDEN_GEOM_GROUP] = 0
            self._scene_camera, self._scene_option = cam, opt
        if scene_name == "room":  # follow the wheelchair, from far enough to see the person and the loudspeaker
            chair = view.body_pose(names.WHEELCHAIR_CHASSIS_BODY)[0]
            self._scene_camera.lookat[:] = (chair[0], chair[1], 0.8)
            self._scene_camera.distance, self._scene_camera.elevation = 6.0, -40.0
        return view.render(self._scene_renderer, self._scene_camera, scene_option=self._scene_option)

    def eye(self, model: mujoco.MjModel, data: mujoco.MjData, size: tuple[int, int]) -> np.ndarray:
        """What the right eye camera sees now: (height, width, 3) uint8, ``size`` = (height, width)."""
        h, w = size
        if self._eye_renderer is None:
            self._eye_renderer = offscreen(model, h, w)
            opt = mujoco.MjvOption()
            opt.sitegroup[:] = 0
            self._eye_option = opt
        return SceneView(model, data).render(self._eye_renderer, names.EYE_CAMERAS[1], scene_option=self._eye_option)

    def close(self) -> None:
        """Free the renderers (they are built again if asked for)."""
        for r in (self._scene_renderer, self._eye_renderer):
            if r is not None:
                r.close()
        self._scene_renderer = self._eye_renderer = None


def offscreen(model: mujoco.MjModel, height: int, width: int):
    """A :class:`mujoco.Renderer` of ``height`` x ``width`` pixels (the model's offscreen
    buffer grown to fit).

    Raises
    ------
    ConfigError
        If no offscreen OpenGL backend works.
    """
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # the GL backends raise RuntimeError, ImportError, OSError, ...
        raise ConfigError(
            f"offscreen rendering failed ({type(err).__name__}: {err}); install libegl1 or libosmesa6, "
            "or set MUJOCO_GL=egl or osmesa"
        ) from err


__all__ = ["Pictures", "offscreen"]
