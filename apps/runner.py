"""The ``run`` command: episodes of a hearing task with a policy, a summary and ``episodes.json``.

:func:`run_episodes` runs ``episodes`` episodes of a task (``reverse-alarm``,
``parking-brake``, ``call-response``) with a policy (``scripted``, ``oracle``, ``blind``, ``deaf``, ``random``,
``random-hold`` or ``module:Class``), episode ``i`` with seed ``seed + i``, and writes ``DIR/episodes.json``: one record per
episode (outcome, success, false release, reaction time, the events) and the summary
``success_rate``, ``median_reaction_s`` (target sound's start to letting go, or to the
person in view, over the episodes that have one) and ``false_release_rate`` (episodes in
which the hand let go before the target sound: on a distractor). A progress bar runs over
the episodes and a summary table is printed at the end.

Hook for recorders: ``step_callback(env, episode, step, obs, reward, terminated, truncated,
info)`` is called after every reset (``step`` 0, reward 0) and every step; the env exposes
``last_percept``, ``last_audio`` and ``coupling`` for what a recording needs.

Recordings: ``rrd=FILE`` (``--rrd FILE`` on the command line) attaches an
:class:`acoustic_sim.viz.episode.EpisodeRecorder` through that hook. All episodes of the run
go into that one file, one after another: the ``frame`` timeline counts every step of the
run, ``sim_time`` is each episode's own time plus an offset that starts it 1 s after the
previous one ended, and an ``episode`` timeline holds the episode number; the event log
marks each episode's start (with its seed) and outcome.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import check_writable_folder, write_text
from policies import POLICIES

TASK_NAMES = ("reverse-alarm", "parking-brake", "call-response")
"""Task names of the command line."""

POLICY_NAMES = POLICIES
"""Policy names of the command line (besides ``module:Class``)."""


def make_env(task: str, *, profile: str = "paper", **kwargs):
    """A task env by its command-line name (``reverse-alarm``, ...), unwrapped."""
    if task not in TASK_NAMES:
        raise ConfigError(f"unknown task {task!r}; valid: {', '.join(TASK_NAMES)}")
    import importlib

    module, cls = {
        "reverse-alarm": ("tasks.reverse_alarm", "ReverseAlarmEnv"),
        "parking-brake": ("tasks.parking_brake", "ParkingBrakeEnv"),
        "call-response": ("tasks.call_response", "CallResponseEnv"),
    }[task]
    return getattr(importlib.import_module(module), cls)(profile=profile, **kwargs)


def _number(x):
    """JSON-friendly float: None for NaN."""
    if x is None:
        return None
    x = float(x)
    return None if math.isnan(x) else round(x, 4)


def run_episode(env, policy, seed: int, *, episode: int = 0, step_callback=None) -> dict:
    """One episode; returns its record."""
    t0 = time.perf_counter()
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info, seed)
    if step_callback is not None:
        step_callback(env, episode, 0, obs, 0.0, False, False, info)
    events, steps, total = [], 0, 0.0
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
        steps += 1
        total += reward
        events += [{k: (round(v, 4) if isinstance(v, float) else v) for k, v in e.items()} for e in info["events"]]
        if step_callback is not None:
            step_callback(env, episode, steps, obs, reward, terminated, truncated, info)
    record = {
        "episode": episode,
        "seed": seed,
        "outcome": info["outcome"],
        "success": bool(info["success"]),
        "false_release": bool(info.get("false_release", False)),
        "reaction_s": _number(info.get("reaction_s")),
        "target_onset_s": _number(info.get("target_onset_s")),
        "steps": steps,
        "episode_s": round(steps / 62.5, 3),
        "return": total,
        "events": events,
        "wall_s": round(time.perf_counter() - t0, 3),
    }
    if info.get("hidden"):
        record["hidden"] = {k: _number(v) for k, v in info["hidden"].items()}
    for key in ("release_s", "found_s", "gear", "teeth", "calls", "person_bearing_deg"):
        if key in info:
            v = info[key]
            record[key] = _number(v) if isinstance(v, (float, np.floating)) else (int(v) if isinstance(v, (np.integer,)) else v)
    return record


CONFIDENCE = 0.95
"""Level of the intervals around the rates (:func:`rate_interval`)."""


def rate_interval(k: int, n: int, confidence: float = CONFIDENCE) -> list[float] | None:
    """Wilson score interval ``[low, high]`` of a rate of ``k`` in ``n`` episodes (None for n = 0).

    Episodes are Bernoulli trials, so a rate from 20 or 30 of them is a draw: 28 of 30 is
    0.93 with a 95 % interval of 0.79-0.98, and 0 of 30 still allows 0.11. Wilson's interval
    (``scipy.stats.binomtest(...).proportion_ci(method="wilson")``) keeps its level near
    nominal at 0 and n, where the normal approximation collapses to a point.
    """
    if n <= 0:
        return None
    if not 0 <= k <= n:
        raise ConfigError(f"rate_interval: k must be within 0..{n}, got {k}")
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return [round(float(ci.low), 4), round(float(ci.high), 4)]


def summarize(records: list[dict]) -> dict:
    """success_rate, median_reaction_s, false_release_rate (each rate with its 95 % Wilson
    interval, ``*_ci95``) and the outcome counts."""
    n = len(records)
    reactions = [r["reaction_s"] for r in records if r["reaction_s"] is not None]
    outcomes: dict[str, int] = {}
    for r in records:
        outcomes[r["outcome"]] = outcomes.get(r["outcome"], 0) + 1
    steps = sum(r["steps"] for r in records)
    wall = sum(r["wall_s"] for r in records)
    successes = sum(bool(r["success"]) for r in records)
    false_releases = sum(bool(r["false_release"]) for r in records)
    return {
        "episodes": n,
        "success_rate": round(successes / n, 4) if n else None,
        "success_rate_ci95": rate_interval(successes, n),
        "median_reaction_s": round(statistics.median(reactions), 4) if reactions else None,
        "false_release_rate": round(false_releases / n, 4) if n else None,
        "false_release_rate_ci95": rate_interval(false_releases, n),
        "outcomes": outcomes,
        "env_steps": steps,
        "wall_s": round(wall, 2),
        "env_steps_per_s": round(steps / wall, 1) if wall > 0 else None,
    }


def _learned_env_kwargs(policy: str, env_kwargs: dict | None) -> dict | None:
    """A ``learned:PATH`` policy's action and reward modes merged into ``env_kwargs`` (others:
    unchanged); ConfigError when the caller asked for other modes."""
    from policies.learned import PREFIX, env_kwargs as learned_kwargs

    if not str(policy).startswith(PREFIX):
        return env_kwargs
    needed = learned_kwargs(str(policy)[len(PREFIX):])
    for key, value in (env_kwargs or {}).items():
        if key in needed and value != needed[key]:
            raise ConfigError(f"{policy} was trained with {key}={needed[key]!r}, not {value!r}")
    return {**(env_kwargs or {}), **needed}


def run_episodes(task: str, policy: str, episodes: int, seed: int, out, profile: str = "paper", progress: bool = True,
                 step_callback=None, rrd=None, camera: bool = True, env_kwargs: dict | None = None) -> dict:
    """Run ``episodes`` episodes and write ``out/episodes.json``.

    Parameters
    ----------
    task : str
        ``reverse-alarm``, ``parking-brake`` or ``call-response``.
    policy : str
        One of :data:`policies.POLICIES` or ``module:Class`` (see :mod:`policies`).
    episodes : int
        Number of episodes, >= 1; episode ``i`` uses seed ``seed + i``.
    seed : int
        Seed of the first episode, >= 0.
    out : str or pathlib.Path
        Output folder (created).
    profile : str
        Auditory pipeline models: ``paper`` or ``fast``.
    progress : bool
        A progress bar over the episodes and the summary table on stdout.
    step_callback : callable, optional
        ``f(env, episode, step, obs, reward, terminated, truncated, info)`` (see the module).
    env_kwargs : dict, optional
        Constructor arguments of the task env (e.g. :data:`tasks.reverse_alarm.PAPER_CAR`).
    rrd : str or pathlib.Path, optional
        Record every episode into this ``.rrd`` file (see the module for the layout); it is
        checked and created before the first episode runs.
    camera : bool
        With ``rrd``: log the eye camera's image (every 4th step).

    Returns
    -------
    dict
        What ``episodes.json`` holds: ``task``, ``policy``, ``profile``, ``seed``,
        ``summary`` (success_rate, median_reaction_s, false_release_rate, outcomes, speed)
        and ``records``; with ``rrd``, also ``rrd`` (the file's path).

    Raises
    ------
    ConfigError
        For an unknown task or policy, or a bad number of episodes or seed.
    RecordingError
        If ``rrd`` cannot take a recording.
    """
    if policy not in POLICY_NAMES and ":" not in str(policy):
        raise ConfigError(f"unknown policy {policy!r}; valid: {', '.join(POLICY_NAMES)} or module:Class")
    if not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise ConfigError(f"episodes must be a positive integer, got {episodes!r}")
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    if task not in TASK_NAMES:
        raise ConfigError(f"unknown task {task!r}; valid: {', '.join(TASK_NAMES)}")
    from policies import policy_class

    policy_class(policy, task)  # an unloadable module:Class fails here, before anything is written
    env_kwargs = _learned_env_kwargs(policy, env_kwargs)
    out = check_writable_folder(out, what="--out")  # before the episodes run, not after
    recorder = None
    if rrd is not None:
        from acoustic_sim.viz.episode import EpisodeRecorder

        recorder = EpisodeRecorder(rrd, camera=camera, first_seed=int(seed), name=f"{task} {policy} seed {int(seed)}")
    callback = _chain(step_callback, recorder)
    records = []
    try:
        env = make_env(task, profile=profile, **(env_kwargs or {}))
        from policies import make_policy

        pol = make_policy(policy, env)
        from acoustic_sim.progress import progress_bar

        bar = progress_bar(range(episodes), desc=f"{task} / {policy}", disable=not progress, dynamic_ncols=True)
        try:
            for i in bar:
                records.append(run_episode(env, pol, int(seed) + i, episode=i, step_callback=callback))
                ok = sum(r["success"] for r in records)
                bar.set_postfix(success=f"{ok}/{len(records)}", last=records[-1]["outcome"])
        finally:
            env.close()
    finally:
        if recorder is not None:
            recorder.close()
    result = {"task": task, "policy": policy, "profile": profile, "seed": int(seed), "summary": summarize(records),
              "records": records}
    if recorder is not None:
        result["rrd"] = str(recorder.path)
    write_text(out / "episodes.json", json.dumps(result, indent=1) + "\n")
    if progress:
        print(summary_table(result))
    return result


def _chain(*callbacks):
    """One step callback that calls each of ``callbacks`` that is not None, in order."""
    live = [c for c in callbacks if c is not None]
    if not live:
        return None
    if len(live) == 1:
        return live[0]

    def call(*args):
        for c in live:
            c(*args)

    return call


def summary_table(result: dict) -> str:
    """The summary as a small text table."""
    s = result["summary"]

    def fmt(v, unit=""):
        return "-" if v is None else (f"{v:.3f}{unit}" if isinstance(v, float) else f"{v}{unit}")

    def rate(key):
        ci = s.get(f"{key}_ci95")
        return fmt(s[key]) + ("" if ci is None else f" (95 % {ci[0]:.2f}-{ci[1]:.2f})")

    rows = [
        ("task", result["task"]), ("policy", result["policy"]), ("profile", result["profile"]),
        ("episodes", fmt(s["episodes"])), ("success_rate", rate("success_rate")),
        ("median_reaction_s", fmt(s["median_reaction_s"], " s")), ("false_release_rate", rate("false_release_rate")),
        ("outcomes", ", ".join(f"{k} {v}" for k, v in sorted(s["outcomes"].items()))),
        ("env_steps_per_s", fmt(s["env_steps_per_s"])),
    ]
    width = max(len(k) for k, _ in rows)
    line = "-" * (width + 3 + max(len(str(v)) for _, v in rows))
    return "\n".join([line, *(f"{k:<{width}} | {v}" for k, v in rows), line])


# -- command line -----------------------------------------------------------------------------------


def add_parsers(sub) -> None:
    """Add ``run`` to the ``acoustic-sim`` subcommands (``cli.build_parser`` calls this)."""
    r = sub.add_parser(
        "run",
        help="run episodes of a hearing task with a policy; write DIR/episodes.json",
        description="Runs episodes of a Gymnasium hearing task (reverse-alarm: put the car into reverse and let go "
        "when the alarm sounds in front; parking-brake: pull the brake and let go when its ratchet sounds on the "
        "right; call-response: turn toward a person who calls until the person is in view) with a policy "
        "(scripted: the paper's behaviour from the percepts; oracle: from the ground truth; blind: ignores "
        "directions; deaf: the best open-loop behaviour, never listening; random, random-hold: random actions, "
        "the second with the hands kept closed; or module:Class, your own). Episode i uses seed SEED + i. Writes DIR/episodes.json (one record per episode, "
        "success_rate, median_reaction_s, false_release_rate) and prints a summary table. With --rrd FILE, "
        "also a rerun recording of every episode (open it with `acoustic-sim play FILE`): all episodes are one "
        "recording, one after another; the frame timeline counts every step of the run, sim_time runs on with "
        "each episode starting 1 s after the previous one ended, an episode timeline numbers them, and the event "
        "log marks each episode's start (with its seed) and outcome.",
    )
    r.add_argument("task", choices=TASK_NAMES, help="which task")
    r.add_argument("--policy", default="scripted", metavar="POLICY",
                   help=f"which policy: {', '.join(POLICY_NAMES)}, learned:PATH (trained by `acoustic-sim train policy`), "
                   "or module:Class (a class built as Class(env) "
                   "with reset(obs, info, seed) and act(obs, info), importable from here); default scripted")
    r.add_argument("--episodes", type=int, default=20, help="number of episodes (default 20)")
    r.add_argument("--seed", type=int, default=0, help="seed of the first episode (default 0)")
    r.add_argument("--out", type=Path, required=True, help="output folder for episodes.json")
    r.add_argument("--profile", choices=("paper", "fast"), default="paper",
                   help="auditory models: paper (default) or fast (small, for tests)")
    r.add_argument("--paper-car", action="store_true",
                   help="reverse-alarm only: the paper's car (R at 15 deg, the alarm as R engages, a 1 s window) "
                   "instead of a car whose R and alarm latency are drawn per episode")
    r.add_argument("--paper-room", action="store_true",
                   help="call-response only: the paper's room (one person, found when in view, no response window) "
                   "instead of three people, one calling, to be looked at within 1.5 s of the call")
    r.add_argument("--action-mode", choices=("joints", "skill"), default=None,
                   help="the env's action space: joints (default; what the built-in policies act in) or skill "
                   "(the small learner's space of tasks/skills.py, for a module:Class policy written for it); "
                   "a learned:PATH policy brings its own")
    r.add_argument("--reward-mode", choices=("sparse", "shaped"), default=None,
                   help="the reward summed into each record's return: sparse (default) or shaped; a learned:PATH "
                   "policy brings its own")
    r.add_argument("--rrd", type=Path, default=None, metavar="FILE",
                   help="also write a rerun recording (FILE ends in .rrd) of all the episodes, one after another "
                   "on the sim_time timeline, numbered on an episode timeline")
    r.add_argument("--no-camera", action="store_true",
                   help="with --rrd: leave out the eye camera images, rendered offscreen every 4th step otherwise "
                   "(fast on a GPU; tens of ms a picture with software OpenGL, which can slow a CPU-only run severalfold)")
    r.set_defaults(func=cmd_run)


def cmd_run(args) -> int:
    if args.episodes < 1:
        raise ConfigError(f"--episodes must be at least 1, got {args.episodes}")
    if args.seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {args.seed}")
    if args.no_camera and args.rrd is None:
        raise ConfigError("--no-camera only applies to a recording: add --rrd FILE")
    env_kwargs = None
    if args.paper_car:
        if args.task != "reverse-alarm":
            raise ConfigError("--paper-car only applies to reverse-alarm")
        from tasks.reverse_alarm import PAPER_CAR

        env_kwargs = dict(PAPER_CAR)
    if args.paper_room:
        if args.task != "call-response":
            raise ConfigError("--paper-room only applies to call-response")
        from tasks.call_response import PAPER_ROOM

        env_kwargs = dict(PAPER_ROOM)
    if args.action_mode == "skill" and ":" not in args.policy:
        raise ConfigError(f"--action-mode skill needs a module:Class policy written for it; the built-in "
                          f"{args.policy!r} acts in the joints mode")
    modes = {k: v for k, v in (("action_mode", args.action_mode), ("reward_mode", args.reward_mode)) if v is not None}
    env_kwargs = {**(env_kwargs or {}), **modes}
    result = run_episodes(args.task, args.policy, args.episodes, args.seed, args.out, profile=args.profile,
                          rrd=args.rrd, camera=not args.no_camera, env_kwargs=env_kwargs)
    print(f"wrote {args.out / 'episodes.json'}")
    if "rrd" in result:
        print(f"wrote {result['rrd']} (view it with: acoustic-sim play {result['rrd']})")
    return 0
