"""Task environment benchmark: env steps per second with hearing in the loop.

For each task (ReverseAlarm, ParkingBrake, CallResponse) and each auditory profile
(``paper``, ``fast``), one env is reset and stepped with the scripted policy's actions for
``steps`` steps (an episode that ends is reset, and the reset is not timed); every step is
a full control step: physics and coupling, rendering, microphone, the auditory pipeline
(exactly one percept) and the observation. ``env_steps_per_s`` is the median over 5
repeats (interleaved across the tasks) of steps per second of wall time. For each profile,
a vector of 2 ReverseAlarm envs (the hand holding the gear knob, episodes reset by the
vector) is stepped with
``gymnasium.vector.AsyncVectorEnv`` (one process per env, so both cores work) and
``SyncVectorEnv``; its figure counts the steps of both envs.

Targets (2 cores): ``paper`` at least 62.5 steps/s (real time: one step is 16 ms of
world), ``fast`` at least 300.
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import time

import numpy as np

TARGETS = {"paper": 62.5, "fast": 300.0}
"""Target env steps per second of a single env, per profile."""

TASKS = ("reverse-alarm", "parking-brake", "call-response")


def _singles(profile: str, steps: int, repeats: int) -> dict:
    """Per task, steps per second of one env over ``repeats`` runs of ``steps`` steps.

    The repeats are interleaved across the tasks (task 1, 2, 3, then again), so a slow spell
    of a shared machine lowers every task's figures alike instead of one task's median.
    """
    from apps.runner import make_env
    from policies import make_policy

    envs = {task: make_env(task, profile=profile) for task in TASKS}
    policies = {task: make_policy("scripted", env) for task, env in envs.items()}
    rates: dict[str, list[float]] = {task: [] for task in TASKS}
    seeds = {task: 0 for task in TASKS}
    try:
        for _ in range(repeats):
            for task in TASKS:
                env, policy = envs[task], policies[task]
                obs, info = env.reset(seed=seeds[task])
                policy.reset(obs, info)
                done, elapsed = 0, 0.0
                while done < steps:
                    action = policy.act(obs, info)
                    t0 = time.perf_counter()
                    obs, _, terminated, truncated, info = env.step(action)
                    elapsed += time.perf_counter() - t0
                    done += 1
                    if terminated or truncated:
                        seeds[task] += 1
                        obs, info = env.reset(seed=seeds[task])
                        policy.reset(obs, info)
                rates[task].append(done / elapsed)
                seeds[task] += 1
    finally:
        for env in envs.values():
            env.close()
    return {task: {"env_steps_per_s": round(statistics.median(r), 1), "runs": [round(v, 1) for v in r], "steps": steps}
            for task, r in rates.items()}


def _make(task: str, profile: str):
    def thunk():
        from apps.runner import make_env

        return make_env(task, profile=profile)

    return thunk


def _vector(profile: str, steps: int, asynchronous: bool) -> dict:
    import gymnasium as gym

    cls = gym.vector.AsyncVectorEnv if asynchronous else gym.vector.SyncVectorEnv
    envs = cls([_make("reverse-alarm", profile) for _ in range(2)])
    try:
        from tasks.base import action_layout, lever_arm_angles

        layout = action_layout("cabin")
        hold = layout.action({**layout.arm("left", lever_arm_angles("left", 0.0)), "grasp_left": 1.0})  # hold the gear knob
        envs.reset(seed=0)
        t0 = time.perf_counter()
        for _ in range(steps):
            envs.step(np.stack([hold, hold]))
        elapsed = time.perf_counter() - t0
    finally:
        envs.close()
    return {"env_steps_per_s": round(2 * steps / elapsed, 1), "steps_per_env": steps}


def run(quick: bool = False) -> dict:
    """Measure; returns the JSON-ready result (``acoustic-sim bench env``)."""
    from apps.runner import make_env  # noqa: F401  (import check before timing)

    steps, repeats = (60, 1) if quick else (400, 5)
    result = {
        "benchmark": "env",
        "quick": quick,
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version()},
        "targets_steps_per_s": TARGETS,
        "profiles": {},
    }
    profiles = ("fast",) if quick else ("fast", "paper")
    for profile in profiles:
        entry = {"tasks": _singles(profile, steps, repeats)}
        single = [v["env_steps_per_s"] for v in entry["tasks"].values()]
        entry["min_env_steps_per_s"] = min(single)
        entry["meets_target"] = min(single) >= TARGETS[profile]
        vec_steps = steps // 2 if quick else steps
        entry["vector_2_async"] = _vector(profile, vec_steps, True)
        entry["vector_2_sync"] = _vector(profile, vec_steps, False)
        result["profiles"][profile] = entry
    return result


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick="--quick" in sys.argv), indent=2))
