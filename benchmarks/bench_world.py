"""World benchmark: physics and coupling per 16 ms control step, without audio rendering.

For each composed scene (``cabin``, ``room``) the robot moves as in a task: the neck sweeps
(+-60 deg yaw, nodding), both arms swing, in the cabin a hand works the gearshift (P -> R ->
N and back) and pulls the parking brake over its teeth, in the room the wheelchair drives
and turns while the person walks; requests (calls, key turns, distractors) are scheduled.
Each control step runs :meth:`Coupling.advance`: 8 physics steps of 2 ms with the
mechanisms traced after each, sound events, ear and source poses in the room frame handed
to the renderer, ego-noise level. Audio rendering (:meth:`Coupling.render`) is timed apart.

``world_step_ms`` is the median over repeats of the mean time per control step of a run
(medians resist other processes on a shared machine); ``physics_ms`` is the same for the 8
``mj_step`` calls alone on the same trajectory, so ``coupling_ms`` is what the coupling adds.
Target: ``world_step_ms`` <= 1 ms on 2 cores (one is used).
"""

from __future__ import annotations

import functools
import os
import platform
import time

import mujoco
import numpy as np

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.world import actuation, names, scenes
from acoustic_sim.world.coupling import Coupling

DEG = np.pi / 180.0
TARGET_MS = 1.0


def _controls(c: Coupling, k: int) -> None:
    """Task-like controls for control step ``k`` (writes ctrl, mocap and the lever hands)."""
    t = k / 62.5
    d, m, v = c.data, c.model, c.view
    act = functools.partial(actuation.set_control, m, d)
    act(names.NECK_JOINTS[0], 60.0 * DEG * np.sin(2 * np.pi * t / 3.2))
    act(names.NECK_JOINTS[1], 15.0 * DEG * np.sin(2 * np.pi * t / 2.1))
    for i, side in enumerate(names.ARM_SIDES):
        act(names.arm_joints(side)[0], 0.3 + 0.25 * np.sin(2 * np.pi * t / 2.5 + i))
        act(names.arm_joints(side)[3], 0.8 + 0.3 * np.sin(2 * np.pi * t / 1.7 + i))
    if v.gearshift_geometry is not None:
        phase = (t % 6.0) / 6.0  # P -> R -> N and back, every 6 s
        gear = np.interp(phase, [0, 0.15, 0.3, 0.45, 0.6, 0.8, 1.0], [0, 0, 15, 15, 30, 30, 0]) * DEG
        actuation.set_joint_force(m, d, names.GEARSHIFT_JOINT,
                                  10.0 * (gear - v.gearshift_angle()) - 0.3 * v.joint_velocity(names.GEARSHIFT_JOINT))
        pull = (t % 4.0) / 4.0  # pull over the teeth, hold, release with the button
        brake = np.interp(pull, [0, 0.6, 1.0], [0, 40, 40]) * DEG
        actuation.set_joint_force(m, d, names.BRAKE_JOINT,
                                  60.0 * (brake - v.brake_angle()) - v.joint_velocity(names.BRAKE_JOINT) if pull < 0.8 else 0.0)
        act(names.BRAKE_RELEASE_ACTUATOR, 1.0 if pull >= 0.8 else 0.0)
    if v.has_joint(names.WHEEL_JOINTS[0]):
        for i, wheel in enumerate(names.WHEEL_JOINTS):
            act(wheel, 1.5 * np.sin(2 * np.pi * t / 5.0) + (0.8 if i else -0.8) * np.sin(2 * np.pi * t / 7.0))
        actuation.place_mocap(m, d, names.PERSON_ROOT_BODY, [4.2 - 0.5 * np.sin(2 * np.pi * t / 8.0), 3.3, 0.0], -150.0)


def _requests(c: Coupling, seconds: float) -> None:
    ev = c.events
    for t in np.arange(0.5, seconds, 1.5):
        if "voice" in ev.emitters:
            ev.schedule_call(float(t))
        if "ignition" in ev.emitters:
            ev.schedule_key_turn(float(t))
        ev.schedule_distractor(float(t) + 0.7, "car_horn")


def _measure(name: str, hrtf, steps: int, repeats: int) -> dict:
    c = Coupling.from_scene(name, rng=np.random.default_rng(0), hrtf=hrtf)
    _requests(c, steps * repeats / 62.5 + 2.0)
    for k in range(30):  # settle and warm caches
        _controls(c, k)
        c.advance()
    # Only advance() is timed: writing the controls is the task's business.
    world, physics, n_events = [], [], 0
    k = 30
    clock = time.perf_counter
    for _ in range(repeats):
        spent = 0.0
        for _ in range(steps):
            _controls(c, k)
            t0 = clock()
            n_events += len(c.advance())
            spent += clock() - t0
            k += 1
        world.append(spent / steps)
    # The same controls with bare physics: what the coupling adds on top.
    m, d = c.model, c.data
    for _ in range(repeats):
        spent = 0.0
        for _ in range(steps):
            _controls(c, k)
            t0 = clock()
            for _ in range(c.n_substeps):
                actuation.step(m, d)
            spent += clock() - t0
            k += 1
        physics.append(spent / steps)
    # Rendering, for reference (a fresh world, so renderer and world clocks agree).
    r = Coupling.from_scene(name, rng=np.random.default_rng(0), hrtf=hrtf)
    _requests(r, steps / 62.5 + 1.0)
    render_steps = steps
    spent = 0.0
    for j in range(render_steps):
        _controls(r, j)
        t0 = clock()
        r.step()
        spent += clock() - t0
    step_ms = spent / render_steps * 1e3
    world_ms, physics_ms = float(np.median(world)) * 1e3, float(np.median(physics)) * 1e3
    return {
        "world_step_ms": round(world_ms, 4),
        "physics_ms": round(physics_ms, 4),
        "coupling_ms": round(world_ms - physics_ms, 4),
        "world_step_ms_min": round(float(np.min(world)) * 1e3, 4),
        "world_step_ms_max": round(float(np.max(world)) * 1e3, 4),
        "step_with_audio_ms": round(step_ms, 3),
        "events": n_events,
        "steps": steps * repeats,
        "model": {"nq": m.nq, "nv": m.nv, "nu": m.nu, "nbody": m.nbody, "ngeom": m.ngeom, "timestep_s": m.opt.timestep},
        "meets_target": world_ms <= TARGET_MS,
    }


def run(*, quick: bool = False) -> dict:
    """Run the benchmark; returns the JSON-ready result (``quick``: shorter, noisier runs)."""
    hrtf = HRTF.load("kemar")
    steps, repeats = (125, 3) if quick else (625, 7)
    measured = {name: _measure(name, hrtf, steps, repeats) for name in scenes.SCENES}
    return {
        "world_step_ms": {name: r["world_step_ms"] for name, r in measured.items()},
        "targets": {"world_step_ms": TARGET_MS},
        "scenes": measured,
        "control_step_ms": 16.0,
        "machine": {
            "cpus": os.cpu_count(),
            "load_average_1min": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None,
            "python": platform.python_version(),
            "mujoco": mujoco.__version__,
            "processor": platform.machine(),
        },
        "quick": quick,
    }
