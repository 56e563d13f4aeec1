"""Gymnasium tasks with hearing in the loop (issue 5), registered under ``acoustic_sim/``.

==============================  =====================================  ======================
id                              class                                  scene
==============================  =====================================  ======================
``acoustic_sim/ReverseAlarm-v0``  :class:`tasks.reverse_alarm.ReverseAlarmEnv`  cabin (gearshift)
``acoustic_sim/ParkingBrake-v0``  :class:`tasks.parking_brake.ParkingBrakeEnv`  cabin (parking brake)
``acoustic_sim/CallResponse-v0``  :class:`tasks.call_response.CallResponseEnv`  room (wheelchair)
==============================  =====================================  ======================

``gymnasium.make("acoustic_sim/ReverseAlarm-v0", profile="fast")`` after ``import acoustic_sim``
(or ``import tasks``; the ids and their TimeLimits: :mod:`acoustic_sim.registration`).
The classes' docstrings are the specifications.

What the tasks share: :mod:`tasks.base` (the env: world, ears and pipeline per step),
:mod:`tasks.cabin` (the two lever tasks), :mod:`tasks.actions` (the action vector),
:mod:`tasks.levers` (the taught lever motions), :mod:`tasks.auditory` (the shared models),
:mod:`tasks.task_sounds` (sounds placed anywhere: ``env.schedule_sound``; the machinery and the
ground truth are :mod:`acoustic_sim.world.soundscape`, stepped by :mod:`acoustic_sim.loop`).
The specifications are written out in each class's docstring; ``tests/spec_docs.py`` holds
the parts they share, which the tests compare them with. Importing this package imports no MuJoCo
or torch (the env modules load on first use: ``gymnasium.make`` or attribute access), so it
can choose MuJoCo's offscreen OpenGL backend first (``render_mode="rgb_array"``, ``image_obs``).
"""

from __future__ import annotations

import importlib

from acoustic_sim.registration import TASK_IDS, register_envs
from acoustic_sim.world.snapshot import choose_gl_backend

# MuJoCo fixes its OpenGL backend when it is first imported; the task modules import it, so
# an offscreen one (EGL or OSMesa, unless MUJOCO_GL says otherwise) is chosen here, first.
choose_gl_backend()

TASKS = {task: (env_id, entry) for task, (env_id, entry, _) in TASK_IDS.items()}
"""Command-line task name -> (Gymnasium id, entry point)."""

register_envs()

_LAZY = {
    "ReverseAlarmEnv": "tasks.reverse_alarm",
    "ParkingBrakeEnv": "tasks.parking_brake",
    "CallResponseEnv": "tasks.call_response",
}

__all__ = ["TASKS", "CallResponseEnv", "ParkingBrakeEnv", "ReverseAlarmEnv"]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'tasks' has no attribute {name!r}")
