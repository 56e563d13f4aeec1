"""Auditory pipeline benchmark: time per ear frame, SSDENet training time, peak memory.

Frame: the reverse alarm on the dashboard of the car cabin, rendered through KEMAR with the
cabin's background and the microphone; the streaming pipeline (front end, log-mel, MelCNN on
both ears, binaural fusion, valid bins and the SSDENet bank over them) processes it block
by block with 2 torch threads. ``frame_ms_median`` is the median wall time of
``AuditoryPipeline.process`` over the frames in which the alarm was detected (the frames
that run SSDENet), so it is the full per-frame cost. ``ssdenet_train_s`` trains the bank of
the profile afresh (not from the cache) on KEMAR and the paper's grid.
"""

from __future__ import annotations

import os
import platform
import resource
import time

import numpy as np
import torch

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory.melcnn import MelCNN
from acoustic_sim.auditory.pipeline import AuditoryPipeline
from acoustic_sim.auditory.ssdenet import SSDENetBank, get_profile, train_bank
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.frames import rotation_zyx


def _alarm_blocks(seconds: float, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    room = room_preset("car_cabin")
    head = np.asarray(room.listener)
    r = BinauralRenderer(HRTF.load("kemar"), room, rng=rng)
    r.set_head_pose(head, rotation_zyx(0.0))
    r.add_source("alarm", sounds.generate("reverse_alarm", rng, seconds=seconds), head + [0.8, 0.0, 0.05], level_db=85.0, start=0)
    mic = Microphone(rng=rng)
    return [mic(r.render_block()) for _ in range(int(seconds * 62.5))]


def run(*, quick: bool = False) -> dict:
    torch.set_num_threads(2)
    profile = "fast" if quick else "paper"
    hrtf = HRTF.load("kemar")
    grid = DirectionGrid.paper(hrtf)
    pipe = AuditoryPipeline(hrtf=hrtf, grid=grid, ssdenet=SSDENetBank.load_or_train(hrtf, grid, profile),
                            melcnn=MelCNN.load_or_train(profile))
    blocks = _alarm_blocks(2.0 if quick else 8.0)
    times, detected, n_bins = [], 0, []
    for b in blocks:
        t0 = time.perf_counter()
        percepts = pipe.process(b)
        dt = time.perf_counter() - t0
        for p in percepts:
            if "reverse_alarm" in p.directions:
                times.append(dt)
                detected += 1
                n_bins.append(p.directions["reverse_alarm"].n_bins)
    all_ms = None
    if not times:  # nothing detected: report the plain per-frame time so the file is never empty
        all_ms = True
        for b in blocks[:50]:
            t0 = time.perf_counter()
            pipe.process(b)
            times.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    prof = get_profile(profile)
    train_bank(hrtf, grid, prof, progress=not quick)
    train_s = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {
        "frame_ms_median": round(float(np.median(times)) * 1e3, 3),
        "frame_ms_p90": round(float(np.percentile(times, 90)) * 1e3, 3),
        "frames_timed": len(times),
        "frames_with_alarm_direction": detected,
        "timed_without_detection": bool(all_ms),
        "valid_bins_median": int(np.median(n_bins)) if n_bins else 0,
        "ssdenet_train_s": round(train_s, 1),
        "ssdenet_parameters": int(pipe.ssdenet.n_parameters()),
        "ssdenet_bins": int(pipe.ssdenet.n_bins),
        "peak_memory_mb": round(peak_mb, 1),
        "profile": profile,
        "targets": {"frame_ms_median": 4.0, "ssdenet_train_s": 600.0},
        "machine": {"cpus": os.cpu_count(), "torch_threads": torch.get_num_threads(), "python": platform.python_version()},
        "quick": quick,
    }
