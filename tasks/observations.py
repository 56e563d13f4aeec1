"""The tasks' observation: its space, and the percept written into it each step.

The observation never holds ground truth (``info`` does). What every task shares: the
robot's proprioception, the percept (class probabilities, per class the estimated and the
tracked direction, the existence map of the most likely class) and the optional raw keys
(the ear block, the ear spectra, the eye image); a task adds its own keys between the
proprioception and the percept (:meth:`tasks.base.HearingTaskEnv._task_spaces`). The keys,
shapes and units are the Observation Space table of each task's docstring.
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE
from tasks.actions import ROBOT_JOINTS

CLASSES: tuple[str, ...] = tuple(SOUND_CLASSES)
"""The six sound classes, in the order of the percept's probabilities."""

BLOCK = math.ceil(SAMPLE_RATE / FRAME_RATE)
"""Samples of the ``audio`` observation (706): a 705-sample block is padded with one zero."""

N_BINS = 1025
"""Spectral bins per ear of the ``spectra`` observation."""


def observation_space(*, n_directions: int, existence_high: float, task_spaces: dict, audio: bool, spectra: bool,
                      image_size: tuple[int, int] | None) -> spaces.Dict:
    """The ``Dict`` observation space of a task.

    Parameters
    ----------
    n_directions : int
        Directions of the pipeline's grid (the ``existence`` map's length).
    existence_high : float
        Highest value of the existence map: the SSDENet bank's number of bins.
    task_spaces : dict
        The task's own keys (after proprioception and the percept in the dict).
    audio, spectra : bool
        Add the ear block (2, 706) and the ear spectra (2, 1025), full scale.
    image_size : tuple of int or None
        (height, width) of the eye image in pixels; None: no image.
    """
    obs = {
        "joint_pos": spaces.Box(-np.pi, np.pi, shape=(len(ROBOT_JOINTS),), dtype=np.float32),
        "joint_vel": spaces.Box(-50.0, 50.0, shape=(len(ROBOT_JOINTS),), dtype=np.float32),
        "class_prob": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
        "class_dir": spaces.Box(-1.0, 1.0, shape=(3 * len(CLASSES),), dtype=np.float32),
        "class_conf": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
        "tracked_dir": spaces.Box(-1.0, 1.0, shape=(3 * len(CLASSES),), dtype=np.float32),
        "tracked_conf": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
        "tracked_decided": spaces.Box(0.0, 1.0, shape=(len(CLASSES),), dtype=np.float32),
        "existence": spaces.Box(0.0, existence_high, shape=(n_directions,), dtype=np.float32),
    }
    obs.update(task_spaces)
    if audio:
        obs["audio"] = spaces.Box(-1.0, 1.0, shape=(2, BLOCK), dtype=np.float32)
    if spectra:
        obs["spectra"] = spaces.Box(0.0, float(N_BINS - 1) ** 2 * 4.0, shape=(2, N_BINS), dtype=np.float32)
    if image_size is not None:
        h, w = image_size
        obs["image"] = spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8)
    return spaces.Dict(obs)


def proprioception(pos: np.ndarray, vel: np.ndarray) -> dict:
    """``joint_pos`` (rad) and ``joint_vel`` (rad/s) of the robot's joints, clipped to the space."""
    return {"joint_pos": np.clip(pos, -np.pi, np.pi), "joint_vel": np.clip(vel, -50.0, 50.0)}


def percept_observation(percept, n_directions: int, existence_high) -> dict:
    """The percept's keys of the observation (zeros where it has nothing, or before the first).

    Parameters
    ----------
    percept : acoustic_sim.auditory.pipeline.Percept or None
    n_directions : int
        The existence map's length.
    existence_high
        The existence map's clip (the space's high).
    """
    probs = np.zeros(len(CLASSES), np.float32)
    dirs = np.zeros((len(CLASSES), 3), np.float32)
    conf = np.zeros(len(CLASSES), np.float32)
    existence = np.zeros(n_directions, np.float32)
    tdir = np.zeros((len(CLASSES), 3), np.float32)
    tconf = np.zeros(len(CLASSES), np.float32)
    tdec = np.zeros(len(CLASSES), np.float32)
    p = percept
    if p is not None:
        probs[:] = [p.probability(c) for c in CLASSES]
        best, best_p = None, -1.0
        for name, d in p.directions.items():
            i = CLASSES.index(name)
            dirs[i] = d.vector
            conf[i] = d.confidence
            if probs[i] > best_p:
                best, best_p = d, probs[i]
        if best is not None:
            existence[:] = np.clip(best.existence, 0.0, existence_high)
        for name, t in p.tracked.items():
            if name in CLASSES:
                i = CLASSES.index(name)
                tdir[i], tconf[i], tdec[i] = t.head_vector, t.confidence, float(t.decided)
    return {
        "class_prob": np.clip(probs, 0.0, 1.0),
        "class_dir": np.clip(dirs, -1.0, 1.0).reshape(-1),
        "class_conf": np.clip(conf, 0.0, 1.0),
        "tracked_dir": np.clip(tdir, -1.0, 1.0).reshape(-1),
        "tracked_conf": np.clip(tconf, 0.0, 1.0),
        "tracked_decided": tdec,
        "existence": existence,
    }


def audio_observation(block: np.ndarray | None) -> np.ndarray:
    """The ``audio`` key: the digital ear block (2, 705 | 706), padded to (2, 706) (zeros before the first)."""
    a = np.zeros((2, BLOCK), np.float32)
    if block is not None:
        a[:, : block.shape[1]] = block
    return a


def sound_labels(sounding: list[dict]) -> np.ndarray:
    """``info["labels"]``: (6,) int8, 1 for each class playing (ground truth)."""
    labels = np.zeros(len(CLASSES), np.int8)
    for snd in sounding:
        labels[CLASSES.index(snd["label"])] = 1
    return labels


__all__ = ["BLOCK", "CLASSES", "N_BINS", "audio_observation", "observation_space", "percept_observation", "proprioception",
           "sound_labels"]
