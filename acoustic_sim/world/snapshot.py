"""A picture of a composed scene: MuJoCo's offscreen renderer to PNG.

The OpenGL backend is chosen before MuJoCo is first imported: ``MUJOCO_GL`` as set by the
user, else EGL where libEGL and a driver for it are present (GPU machines, and Mesa's EGL
on CPU ones), else OSMesa (Debian's ``libosmesa6``). ``.ci/run`` installs both.
"""

from __future__ import annotations

import ctypes.util
import dataclasses
import os
import sys
from pathlib import Path

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import atomic_path, check_writable


def choose_gl_backend() -> str:
    """Set ``MUJOCO_GL`` (egl or osmesa) unless the user has; return the backend in use.

    Must run before ``mujoco`` is imported for the first time to have an effect; if MuJoCo
    was already imported, its choice stands and is returned.
    """
    if "MUJOCO_GL" not in os.environ and "mujoco" not in sys.modules:
        os.environ["MUJOCO_GL"] = "egl" if _egl_usable() or not ctypes.util.find_library("OSMesa") else "osmesa"
    return os.environ.get("MUJOCO_GL", "glfw")


def _egl_usable() -> bool:
    """libEGL and a driver behind it (a GLVND vendor file, or Mesa's or NVIDIA's EGL library)."""
    if not ctypes.util.find_library("EGL"):
        return False
    vendor_dirs = (Path("/usr/share/glvnd/egl_vendor.d"), Path("/etc/glvnd/egl_vendor.d"))
    return any(any(d.glob("*.json")) for d in vendor_dirs if d.is_dir()) or any(
        ctypes.util.find_library(lib) for lib in ("EGL_mesa", "EGL_nvidia")
    )


@dataclasses.dataclass(frozen=True, kw_only=True)
class View:
    """A free camera looking at a point."""

    lookat: tuple[float, float, float]
    """Point the camera looks at (m, world)."""

    distance: float
    """Distance from the camera to ``lookat`` (m)."""

    azimuth: float
    """Direction the camera looks, deg counter-clockwise from +x (MuJoCo's free camera)."""

    elevation: float
    """Camera pitch, deg (negative looks down)."""


VIEWS = {
    # From above the bonnet, through the (hidden) windscreen and roof: face, hands, both levers.
    "cabin": View(lookat=(0.95, 0.98, 0.36), distance=1.65, azimuth=-168.0, elevation=-55.0),
    # From the robot's front left: the robot on its wheelchair, the person, the loudspeaker.
    "room": View(lookat=(2.9, 2.3, 0.85), distance=3.0, azimuth=-105.0, elevation=-25.0),
}
"""The fixed camera of each scene."""

HIDDEN_GEOM_GROUP = 1
"""Geom group left out of snapshots: the cabin's windows and roof, which would veil the view."""


def _hands_on_levers(model, data) -> None:
    """Pose the arms with the palms on the gear knob and the brake handle (for the picture)."""
    from acoustic_sim.world import actuation, names
    from acoustic_sim.world.view import SceneView

    view = SceneView(model, data)
    for side in names.ARM_SIDES:
        angles = actuation.reach(model, data, side, view.site_position(names.GRASP_TARGET_SITES[side]))
        for joint, angle in zip(names.arm_joints(side), angles):
            actuation.set_joint_position(model, data, joint, angle)
            actuation.set_control(model, data, joint, angle)
    actuation.forward(model, data)


def snapshot(scene: str, out: Path, width: int = 1280, height: int = 800) -> Path:
    """Render ``scene`` in its initial state from its fixed camera and write a PNG.

    The cabin is shown with the robot's hands on the gear knob and the brake handle.

    Parameters
    ----------
    scene : str
        ``cabin`` or ``room``.
    out : pathlib.Path
        PNG file to write; its folder is created.
    width, height : int
        Image size in pixels, 16-4096 each.

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    ConfigError
        For an unknown scene, a bad size, a file name that is not ``.png``, or no working
        offscreen OpenGL backend.
    """
    if scene not in VIEWS:
        raise ConfigError(f"unknown scene {scene!r}; valid scenes: {', '.join(VIEWS)}")
    for what, value in (("width", width), ("height", height)):
        if not isinstance(value, int) or not 16 <= value <= 4096:
            raise ConfigError(f"snapshot {what} must be an integer 16-4096 pixels, got {value!r}")
    out = Path(out)
    if out.suffix.lower() != ".png":
        raise ConfigError(f"snapshot writes PNG: the file name must end in .png, got {out}")
    check_writable(out, what="--out")
    imported_before = "mujoco" in sys.modules
    backend = choose_gl_backend()
    if imported_before and backend == "glfw" and not os.environ.get("DISPLAY"):
        raise ConfigError(
            "MuJoCo was imported before an offscreen OpenGL backend was chosen and there is no display: "
            "set MUJOCO_GL=egl (or osmesa) in the environment"
        )
    import mujoco
    from PIL import Image

    from acoustic_sim.world.scenes import load_scene
    from acoustic_sim.world.view import SceneView

    model, data, _ = load_scene(scene)
    if scene == "cabin":
        _hands_on_levers(model, data)
    model.vis.global_.offwidth = max(int(model.vis.global_.offwidth), width)
    model.vis.global_.offheight = max(int(model.vis.global_.offheight), height)
    model.vis.quality.offsamples = 8
    view = VIEWS[scene]
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = view.lookat
    camera.distance, camera.azimuth, camera.elevation = view.distance, view.azimuth, view.elevation
    options = mujoco.MjvOption()
    options.sitegroup[:] = 0  # sites are markers for code, not part of the picture
    options.geomgroup[HIDDEN_GEOM_GROUP] = 0
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as err:  # the GL backends raise RuntimeError, ImportError, OSError, ...
        raise ConfigError(
            f"offscreen rendering with MUJOCO_GL={backend} failed ({type(err).__name__}: {err}); install libegl1 "
            "or libosmesa6 (.ci/run does), or set MUJOCO_GL=egl or osmesa"
        ) from err
    with renderer:
        pixels = SceneView(model, data).render(renderer, camera, scene_option=options)
    with atomic_path(out) as tmp:
        Image.fromarray(pixels).save(tmp, format="PNG")
    return out
