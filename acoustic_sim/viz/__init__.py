"""See what the robot heard: rerun recordings of episodes, their layout, and playback.

>>> with Recorder.open("runs/demo.rrd", model, grid.vectors) as rec:   # doctest: +SKIP
...     rec.log_frame(t, k, view=view, head_pose=view.head_pose(), percept=percept,
...                   audio_block=block, sources=[("alarm", "reverse_alarm", pos)])

Task episodes are recorded through the episode runner's hook with
:class:`~acoustic_sim.viz.episode.EpisodeRecorder` (``acoustic-sim run ... --rrd FILE``).
"""

# MuJoCo picks its OpenGL backend when it is first imported (the recorder imports it): choose
# an offscreen one first, so that the eye camera of a recorded episode renders headless.
from acoustic_sim.world.snapshot import choose_gl_backend

choose_gl_backend()

from acoustic_sim.viz.blueprint import default_blueprint
from acoustic_sim.viz.episode import EpisodeRecorder
from acoustic_sim.viz.play import check_recording, has_display, play
from acoustic_sim.viz.recorder import Recorder, RecorderConfig, RecordingError
from acoustic_sim.viz.scene_geometry import SceneGeometry

__all__ = [
    "EpisodeRecorder", "Recorder", "RecorderConfig", "RecordingError", "SceneGeometry", "check_recording",
    "default_blueprint", "has_display", "play",
]
