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

What a learner meets (issue 34): ``reset_ms`` per task (median of ``resets`` resets, with
where the time goes: the scene's compilation, the sounds drawn when the episode is
scheduled, the 0.5 s listening warm-up, and the rest); ``learner_steps_per_s``, one env in
the skill action mode stepped with clipped unit-Gaussian actions (PPO's first policy),
resets included; and ``scaling``: stable-baselines3's ``SubprocVecEnv`` and gymnasium's
``AsyncVectorEnv`` of CallResponse in the skill mode with 1 and 2 workers (one torch thread
each), env steps per second of all workers together, resets included.

Targets (2 cores): ``paper`` at least 62.5 steps/s (real time: one step is 16 ms of
world), ``fast`` at least 300; a learner's: ``reset_ms`` at most 50, ``fast`` at least 500
steps/s with resets in the skill mode, 2 workers at least 1.7 times one.
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

LEARNER_TARGETS = {"reset_ms": 50.0, "fast_learner_steps_per_s": 500.0, "paper_learner_steps_per_s": 62.5,
                   "scaling_2_over_1": 1.7}
"""Issue 34's targets for a learner."""

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


def _make(task: str, profile: str, *, one_thread: bool = False, **env_kwargs):
    """A picklable env factory for the vector envs (``one_thread``: one torch thread in the worker)."""

    def thunk():
        from apps.runner import make_env

        if one_thread:
            import torch

            torch.set_num_threads(1)
        return make_env(task, profile=profile, **env_kwargs)

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


def _resets(profile: str, resets: int) -> dict:
    """Per task, the median reset time (ms) and its parts: the scene's compilation
    (``scenes.load_scene``), the episode's schedule (``_schedule``: the sounds drawn then),
    the listening warm-up (``HearingLoop.warm_up``) and the rest (renderer, coupling, models'
    state), each the median over the resets."""
    from acoustic_sim import loop
    from acoustic_sim.world import scenes
    from apps.runner import make_env

    out = {}
    for task in TASKS:
        env = make_env(task, profile=profile, action_mode="skill")
        parts: dict[str, float] = {}

        def timed(owner, name, key):
            inner = getattr(owner, name)

            def wrapper(*a, **k):
                t0 = time.perf_counter()
                try:
                    return inner(*a, **k)
                finally:
                    parts[key] = parts.get(key, 0.0) + time.perf_counter() - t0

            return inner, wrapper

        patches = [(scenes, "load_scene", "scene_ms"), (loop.HearingLoop, "warm_up", "warm_up_ms"),
                   (type(env), "_schedule", "schedule_ms")]
        saved = []
        rows = []
        try:
            for owner, name, key in patches:
                inner, wrapper = timed(owner, name, key)
                saved.append((owner, name, inner))
                setattr(owner, name, wrapper)
            env.reset(seed=0)  # models loaded, caches warm
            for seed in range(1, resets + 1):
                parts.clear()
                t0 = time.perf_counter()
                env.reset(seed=seed)
                total = time.perf_counter() - t0
                rows.append({"reset_ms": 1000 * total, **{k: 1000 * v for k, v in parts.items()}})
        finally:
            for owner, name, inner in saved:
                setattr(owner, name, inner)
            env.close()
        keys = ["reset_ms", "scene_ms", "schedule_ms", "warm_up_ms"]
        med = {k: round(statistics.median(r.get(k, 0.0) for r in rows), 1) for k in keys}
        med["other_ms"] = round(statistics.median(r["reset_ms"] - sum(r.get(k, 0.0) for k in keys[1:]) for r in rows), 1)
        out[task] = {**med, "resets": resets}
    return out


def _gaussian_actions(space, seed: int):
    rng = np.random.default_rng(seed)
    while True:
        yield np.clip(rng.standard_normal(space.shape), -1.0, 1.0).astype(np.float32)


def _learner(profile: str, steps: int) -> dict:
    """Per task, env steps per second of one skill-mode env with clipped Gaussian actions,
    resets included, and the episodes' mean length."""
    from apps.runner import make_env

    out = {}
    for task in TASKS:
        env = make_env(task, profile=profile, action_mode="skill", reward_mode="shaped")
        try:
            env.reset(seed=0)
            actions = _gaussian_actions(env.action_space, 0)
            episodes, seed = 0, 1
            t0 = time.perf_counter()
            env.reset(seed=seed)
            for _ in range(steps):
                _, _, terminated, truncated, _ = env.step(next(actions))
                if terminated or truncated:
                    episodes += 1
                    seed += 1
                    env.reset(seed=seed)
            elapsed = time.perf_counter() - t0
        finally:
            env.close()
        out[task] = {"learner_steps_per_s": round(steps / elapsed, 1), "steps": steps,
                     "mean_episode_steps": round(steps / max(episodes, 1), 1)}
    return out


def _skill_env(task: str, profile: str):
    return _make(task, profile, one_thread=True, action_mode="skill", reward_mode="shaped")


def _scaling(profile: str, steps: int, task: str = "call-response") -> dict:
    """Env steps per second of 1 and 2 workers in subprocesses (stable-baselines3's
    SubprocVecEnv, gymnasium's AsyncVectorEnv), resets included (the vectors reset ended
    episodes themselves)."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import SubprocVecEnv

    out = {}
    for kind in ("sb3_subproc", "gymnasium_async"):
        rates = {}
        for n in (1, 2):
            if kind == "sb3_subproc":
                venv = SubprocVecEnv([_skill_env(task, profile) for _ in range(n)])
                venv.seed(0)
                venv.reset()
                space = venv.action_space
                step = venv.step
            else:
                venv = gym.vector.AsyncVectorEnv([_skill_env(task, profile) for _ in range(n)])
                venv.reset(seed=0)
                space = venv.single_action_space
                step = venv.step
            try:
                actions = _gaussian_actions(space, 0)
                for _ in range(10):  # the workers' first steps (caches, imports) are not timed
                    step(np.stack([next(actions) for _ in range(n)]))
                t0 = time.perf_counter()
                for _ in range(steps):
                    step(np.stack([next(actions) for _ in range(n)]))
                rates[n] = n * steps / (time.perf_counter() - t0)
            finally:
                venv.close()
        out[kind] = {"workers_1_steps_per_s": round(rates[1], 1), "workers_2_steps_per_s": round(rates[2], 1),
                     "scaling_2_over_1": round(rates[2] / rates[1], 2)}
    out["task"] = task
    out["steps_per_worker"] = steps
    return out


def run(quick: bool = False, profile: str | None = None) -> dict:
    """Measure; returns the JSON-ready result (``acoustic-sim bench env``); ``profile``: that
    profile only (default both, ``fast`` only when ``quick``)."""
    from apps.runner import make_env  # noqa: F401  (import check before timing)

    steps, repeats = (60, 1) if quick else (400, 5)
    result = {
        "benchmark": "env",
        "quick": quick,
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version()},
        "targets_steps_per_s": TARGETS,
        "learner_targets": LEARNER_TARGETS,
        "profiles": {},
    }
    profiles = (profile,) if profile else (("fast",) if quick else ("fast", "paper"))
    for profile in profiles:
        entry = {"tasks": _singles(profile, steps, repeats)}
        single = [v["env_steps_per_s"] for v in entry["tasks"].values()]
        entry["min_env_steps_per_s"] = min(single)
        entry["meets_target"] = min(single) >= TARGETS[profile]
        vec_steps = steps // 2 if quick else steps
        entry["vector_2_async"] = _vector(profile, vec_steps, True)
        entry["vector_2_sync"] = _vector(profile, vec_steps, False)
        entry["reset"] = _resets(profile, 3 if quick else 20)
        entry["learner"] = _learner(profile, 100 if quick else 2000)
        entry["scaling"] = _scaling(profile, 30 if quick else 600)
        worst = max(v["reset_ms"] for v in entry["reset"].values())
        slowest = min(v["learner_steps_per_s"] for v in entry["learner"].values())
        entry["learner_targets_met"] = {
            "reset_ms": worst <= LEARNER_TARGETS["reset_ms"],
            "learner_steps_per_s": slowest >= LEARNER_TARGETS[f"{profile}_learner_steps_per_s"],
            "scaling_2_over_1": entry["scaling"]["sb3_subproc"]["scaling_2_over_1"] >= LEARNER_TARGETS["scaling_2_over_1"],
        }
        result["profiles"][profile] = entry
    return result


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick="--quick" in sys.argv), indent=2))
