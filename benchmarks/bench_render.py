"""Renderer benchmark: real-time factors with a turning head, and the speed-up against
pyroomacoustics re-simulating the same scene for every pose.

Scene: the ``car_cabin`` preset with the bundled KEMAR HRTF, the head at the driver's
position turning sinusoidally (+-60 deg, up to 120 deg/s), a new pose every 16 ms on the
project clock. Sources: the reverse alarm on the dashboard; for 3 sources also a
gearshift sound at the lever and a voice behind. Everything the renderer does per block is
timed: early responses, cross-fades, late tails, background noise, and the microphone.
The renderer runs with its defaults: the direct path follows every pose, the reflections
are re-rendered at the lower rate its module docstring documents (recorded in ``scene``).

Baseline: pyroomacoustics with the same SOFA file as its measured directivity (built once,
re-oriented per pose), the same room materials and the same image-source order, computing
the binaural response for each pose; its time per pose against our time per block, for
one source, is ``speedup_vs_pyroomacoustics``. pyroomacoustics' response only *exists*
after that call; convolving the signal with it would add more.
"""

from __future__ import annotations

import os
import platform
import time

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.acoustics.reference import PraBinaural
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE, rotation_zyx


def _yaw(k: int) -> float:
    return 60.0 * np.sin(2 * np.pi * k / (FRAME_RATE * 3.2))


def _streaming_rtf(hrtf, room, n_sources: int, seconds: float, seed: int = 0) -> tuple[float, float]:
    rng = np.random.default_rng(seed)
    head = np.asarray(room.listener)
    r = BinauralRenderer(hrtf, room, rng=rng)
    placements = [
        ("reverse_alarm", head + [0.8, 0.0, 0.05], 85.0),
        ("gearshift", head + [0.35, 0.3, -0.35], 70.0),
        ("human_voice", head + [-0.6, -0.3, 0.1], 65.0),
    ]
    for name, pos, level in placements[:n_sources]:
        r.add_source(name, sounds.generate(name, rng, seconds=4.0), pos, level_db=level, start=0, loop=True)
    mic = Microphone(rng=rng)
    n_blocks = int(seconds * FRAME_RATE)
    rotations = [rotation_zyx(_yaw(k)) for k in range(n_blocks)]
    for k in range(5):  # warm caches and allocators
        r.set_head_pose(head, rotations[k])
        mic(r.render_block())
    samples = 0
    t0 = time.perf_counter()
    for k in range(n_blocks):
        r.set_head_pose(head, rotations[k])
        samples += mic(r.render_block()).shape[1]
    wall = time.perf_counter() - t0
    return samples / SAMPLE_RATE / wall, wall / n_blocks * 1e3


def _pra_ms_per_pose(hrtf, room, poses: int) -> float:
    head = np.asarray(room.listener)
    ref = PraBinaural(hrtf.source, room)
    ref.brir(head + [0.8, 0.0, 0.05], head, 0.0)  # warm-up
    t0 = time.perf_counter()
    for k in range(poses):
        ref.brir(head + [0.8, 0.0, 0.05], head, _yaw(k))
    return (time.perf_counter() - t0) / poses * 1e3


def _reflection_update_defaults() -> dict:
    """The renderer's default reflection update rule (what the timed scene uses)."""
    import inspect

    params = inspect.signature(BinauralRenderer).parameters
    return {name: params[name].default for name in ("reflection_interval", "reflection_turn_deg", "reflection_move_m")}


def run(*, quick: bool = False) -> dict:
    hrtf = HRTF.load("kemar")
    room = room_preset("car_cabin")
    seconds = 2.0 if quick else 10.0
    rtf1, ms1 = _streaming_rtf(hrtf, room, 1, seconds)
    rtf3, ms3 = _streaming_rtf(hrtf, room, 3, seconds)
    pra_ms = _pra_ms_per_pose(hrtf, room, 5 if quick else 30)
    return {
        "rtf_moving_head_1src": round(rtf1, 2),
        "rtf_moving_head_3src": round(rtf3, 2),
        "speedup_vs_pyroomacoustics": round(pra_ms / ms1, 1),
        "ms_per_block_1src": round(ms1, 3),
        "ms_per_block_3src": round(ms3, 3),
        "pyroomacoustics_ms_per_pose": round(pra_ms, 2),
        "targets": {"rtf_moving_head_1src": 50, "rtf_moving_head_3src": 20, "speedup_vs_pyroomacoustics": 100},
        "scene": {
            "room": room.name, "ism_order": room.ism_order, "hrtf": hrtf.name, "seconds": seconds, "block_ms": 16.0,
            "reflection_update": _reflection_update_defaults(),
        },
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "processor": platform.machine()},
        "quick": quick,
    }
