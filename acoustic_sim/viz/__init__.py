"""See what the robot heard: rerun recordings of episodes, their layout, and playback.

>>> with Recorder.open("runs/demo.rrd", model, grid.vectors) as rec:   # doctest: +SKIP
...     rec.log_frame(t, k, data=data, head_pose=view.head_pose(), percept=percept,
...                   audio_block=block, sources=[("alarm", "reverse_alarm", pos)])
"""

from acoustic_sim.viz.blueprint import default_blueprint
from acoustic_sim.viz.play import check_recording, has_display, play
from acoustic_sim.viz.recorder import Recorder, RecorderConfig, RecordingError
from acoustic_sim.viz.scene import SceneGeometry

__all__ = [
    "Recorder", "RecorderConfig", "RecordingError", "SceneGeometry", "check_recording", "default_blueprint",
    "has_display", "play",
]
