"""Recording benchmark: what logging an episode to rerun costs, per frame and per minute.

Scene: the composed ``cabin`` scene (``world.scenes``; the cabin and robot assets attached the
same way where that module is not there yet). Per ear frame (62.5 Hz), everything an episode
logs: body poses (the joints moving), three labelled sources, the head turning, the true and
estimated directions, an existence map over the paper's direction grid (KEMAR), a (2, 128)
mel frame, six class probabilities, an audio block of 705/706 samples per ear, events now and
then, and a 320x240 eye-camera image (rendered by MuJoCo when an OpenGL backend works, else a
synthetic one) given every frame (the recorder keeps every ``camera_every``-th).

``log_ms_per_frame`` is the wall time of all ``log_frame`` calls plus ``close()`` (the last
flush and the file's footer) divided by the number of frames; preparing the inputs is not
timed. ``log_cpu_ms_per_frame`` is the process CPU time over the same span, so rerun's own
background threads (batching, compression, writing) are counted too. ``rrd_mb_per_min`` is the
file size per minute of simulated time (1 MB = 1e6 bytes). Setting up (the static scene,
the blueprint) is ``open_ms``, once per recording.

``episode`` (not with ``--quick``): the real path of ``acoustic-sim run --rrd``, the
:class:`~acoustic_sim.viz.episode.EpisodeRecorder` on the runner's hook over three
ReverseAlarm episodes with the scripted policy and the ``fast`` models (trained first if
they are not cached): ``hook_ms_per_step`` without the eye camera (everything but the
rendering, the recorder's opening included), ``eye_render_ms`` for one eye image
(``env.eye_image()``, MuJoCo's offscreen renderer: the camera's cost, paid every
``camera_every``-th step) and ``rrd_mb_per_min`` with the camera.
"""

from __future__ import annotations

import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from acoustic_sim.world.snapshot import choose_gl_backend

choose_gl_backend()  # before MuJoCo is imported: the eye camera renders offscreen (EGL or OSMesa)

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.frames import FRAME_RATE
from acoustic_sim.viz.recorder import Recorder, RecorderConfig
from acoustic_sim.viz.sample import SyntheticEpisode, scene_model


def _entity_mb(path: Path) -> dict:
    """Uncompressed arrow size per top-level entity group (MB), read back with rerun."""
    import rerun as rr

    sizes: dict[str, float] = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        parts = chunk.entity_path.strip("/").split("/")
        key = "/".join(parts[:2]) if parts[0] in ("world", "audio", "camera", "percept") else parts[0]
        if key.startswith("world/") and key not in ("world/hearing", "world/sources"):
            key = "world/<scene bodies>"
        sizes[key] = sizes.get(key, 0.0) + chunk.to_record_batch().nbytes / 1e6
    return {k: round(v, 2) for k, v in sorted(sizes.items(), key=lambda kv: -kv[1])}


def episode_cost(n_episodes: int = 3) -> dict:
    """What recording real task episodes through the runner's hook costs (see the module)."""
    from apps.runner import make_env, run_episode
    from acoustic_sim.viz.episode import EpisodeRecorder

    from policies import make_policy

    env = make_env("reverse-alarm", profile="fast")
    policy = make_policy("scripted", env)
    out: dict = {"task": "reverse-alarm", "policy": "scripted", "profile": "fast", "episodes": n_episodes}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for camera in (False, True):
                path = Path(tmp) / f"episode_{camera}.rrd"
                rec = EpisodeRecorder(path, camera=camera)
                spent, steps = [0.0], 0

                def hook(*args, rec=rec, spent=spent):
                    t0 = time.perf_counter()
                    rec(*args)
                    spent[0] += time.perf_counter() - t0

                for i in range(n_episodes):
                    steps += run_episode(env, policy, i, episode=i, step_callback=hook)["steps"]
                t0 = time.perf_counter()
                rec.close()
                spent[0] += time.perf_counter() - t0
                frames = steps + n_episodes
                if not camera:
                    out["hook_ms_per_step"] = round(spent[0] / frames * 1e3, 4)
                    out["steps"] = steps
                else:
                    out["hook_ms_per_step_with_camera"] = round(spent[0] / frames * 1e3, 4)
                    out["camera_every"] = rec.config.camera_every
                    out["rrd_mb_per_min"] = round(path.stat().st_size / 1e6 / (steps / FRAME_RATE / 60.0), 2)
            t0 = time.perf_counter()
            for _ in range(20):
                env.eye_image()
            out["eye_render_ms"] = round((time.perf_counter() - t0) / 20 * 1e3, 2)
            out["eye_image"] = list(env.image_size)
            out["mujoco_gl"] = os.environ.get("MUJOCO_GL", "")
    finally:
        env.close()
    return out


def run(*, quick: bool = False, out_rrd: Path | None = None) -> dict:
    seconds = 10.0 if quick else 60.0
    n_frames = round(seconds * FRAME_RATE)
    model, scene_from = scene_model("cabin")
    grid = DirectionGrid.paper(HRTF.load("kemar")).vectors
    episode = SyntheticEpisode(model, grid, seed=0)
    config = RecorderConfig(application_id="acoustic_sim_bench")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(out_rrd) if out_rrd is not None else Path(tmp) / "bench.rrd"
        t0 = time.perf_counter()
        rec = Recorder.open(path, model, grid, config=config)
        open_ms = (time.perf_counter() - t0) * 1e3
        per_call = np.empty(n_frames)
        wall = 0.0
        cpu = 0.0
        for k in range(n_frames):
            kwargs = episode.frame(k)
            c0, w0 = time.process_time(), time.perf_counter()
            rec.log_frame((k + 1) / FRAME_RATE, k, **kwargs)
            w1, c1 = time.perf_counter(), time.process_time()
            per_call[k] = w1 - w0
            wall += w1 - w0
            cpu += c1 - c0
        c0, w0 = time.process_time(), time.perf_counter()
        rec.close()
        close_s = time.perf_counter() - w0
        wall += close_s
        cpu += time.process_time() - c0
        size = path.stat().st_size
        by_entity = _entity_mb(path) if not quick else None
    minutes = n_frames / FRAME_RATE / 60.0
    result = {
        "log_ms_per_frame": round(wall / n_frames * 1e3, 4),
        "rrd_mb_per_min": round(size / 1e6 / minutes, 2),
        "log_cpu_ms_per_frame": round(cpu / n_frames * 1e3, 4),
        "log_frame_ms_p50": round(float(np.median(per_call)) * 1e3, 4),
        "log_frame_ms_p99": round(float(np.percentile(per_call, 99)) * 1e3, 4),
        "close_ms": round(close_s * 1e3, 1),
        "open_ms": round(open_ms, 1),
        "rrd_mb": round(size / 1e6, 2),
        "targets": {"log_ms_per_frame": 1.0, "rrd_mb_per_min": 30.0},
        "scene": {
            "from": scene_from, "bodies": int(model.nbody), "geoms": int(model.ngeom),
            "seconds": seconds, "frames": n_frames, "grid_directions": len(grid),
            "camera": f"320x240 uint8 every frame, {episode.image_source}; logged every {config.camera_every}th as JPEG q{config.jpeg_quality}",
            "flush_every": config.flush_every, "spectrogram_every": config.spectrogram_every,
        },
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "processor": platform.machine()},
        "quick": quick,
    }
    if by_entity is not None:
        result["uncompressed_mb_by_entity"] = by_entity
    if not quick:
        result["episode"] = episode_cost()
    return result


if __name__ == "__main__":
    import json
    import sys

    print(json.dumps(run(quick="--quick" in sys.argv), indent=2))
