"""The deaf baseline's search (``acoustic-sim deaf-search TASK``): the open-loop parameters
that maximise success on design seeds.

The deaf policy (:mod:`policies.deaf`) is only a bound on what hearing is worth if it is the
*best* behaviour that never listens, not a strawman. So its parameters are searched: every
point of the task's grid (:data:`GRIDS`; the lever's speed, wait and angle, or the room's
scan rate, jump and direction) runs on the same design seeds (by default the first
``--episodes`` of 100-299, :data:`apps.eval_tasks.DESIGN_SEEDS`), and the point with the
highest success wins (ties: the lower median reaction, then the grid's order). The
percept is never read, so the auditory models do not change a deaf episode; the search uses
the small ``fast`` ones for speed. Writes ``OUT/deaf_search.json`` (every point's summary
and the winner) and prints the ranking; the class defaults in :mod:`policies.deaf` are the
winners, and docs/notes/deaf_baseline.md records the runs.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import check_writable_folder, write_text

GRIDS = {
    "reverse-alarm": {"rate_deg_s": (8.0, 16.0), "wait_s": tuple(round(0.2 * i, 1) for i in range(1, 9))},
    "parking-brake": {"target_deg": (9.0, 11.0, 13.0), "rate_deg_s": (4.0, 8.0, 16.0),
                      "wait_s": (0.0, 0.3, 0.6, 1.0)},
    "call-response": {"turn_deg_s": (20.0, 29.0, 60.0, 120.0, 240.0), "step_deg": (0.0, 45.0, 90.0),
                      "direction": (1, -1)},
}
"""Per task, the values of each open-loop parameter searched (their product is the grid).
ReverseAlarm: the push's speed (deg/s; the taught 8 and twice it) and the wait (s) from the
felt detent to letting go, 0.2-1.6 s (the relay's latency is 0.1-1.5 s: a wait outside
loses cars without winning any).
ParkingBrake: lever angles (deg) around the first brake tooth (8 deg, the default
requirement), speeds around the taught 8, waits up to the success window. CallResponse:
scan rates (deg/s) from a sweep slow enough to count as still (below 30 deg/s) to the
wheelchair's top speed, as a sweep or in jumps of 45 or 90 deg (a stop to look after each),
both ways."""

DEFAULT_EPISODES = 40
"""Design seeds per grid point by default (100-139)."""


def grid_points(task: str) -> list[dict]:
    """Every parameter combination of ``task``'s grid, in the grid's order."""
    if task not in GRIDS:
        raise ConfigError(f"unknown task {task!r}; valid: {', '.join(GRIDS)}")
    grid = GRIDS[task]
    return [dict(zip(grid, values)) for values in itertools.product(*grid.values())]


def search(task: str, *, episodes: int = DEFAULT_EPISODES, seed: int = 100, profile: str = "fast",
           progress: bool = True) -> dict:
    """Run every grid point of ``task`` on seeds ``seed``..``seed + episodes - 1``; returns the
    points' summaries (``points``, in the grid's order) and the ``best`` one.

    Raises
    ------
    ConfigError
        For an unknown task, fewer than one episode, or seeds outside the design ranges.
    """
    from apps.eval_tasks import design_seeds_text, held_out
    from apps.runner import make_env, run_episode, summarize
    from policies import make_policy
    from acoustic_sim.progress import progress_bar

    if not isinstance(episodes, int) or episodes < 1:
        raise ConfigError(f"episodes must be a positive integer, got {episodes!r}")
    if seed < 0 or held_out(seed, seed + episodes - 1) or not _within_design(seed, seed + episodes - 1):
        raise ConfigError(f"the search must run on design seeds ({design_seeds_text()}), got {seed}-{seed + episodes - 1}")
    points = grid_points(task)
    env = make_env(task, profile=profile)
    results = []
    bar = progress_bar(total=len(points) * episodes, desc=f"deaf search {task}", disable=not progress)
    try:
        for params in points:
            policy = make_policy("deaf", env, **params)
            records = []
            for i in range(episodes):
                records.append(run_episode(env, policy, seed + i, episode=i))
                bar.update(1)
            s = summarize(records)
            results.append({"params": params, **{k: s[k] for k in ("success_rate", "success_rate_ci95",
                                                                     "false_release_rate", "median_reaction_s",
                                                                     "outcomes")}})
    finally:
        bar.close()
        env.close()
    best = max(range(len(results)), key=lambda i: (results[i]["success_rate"],
                                                    -(results[i]["median_reaction_s"] or float("inf")), -i))
    return {"task": task, "profile": profile, "seed": int(seed), "episodes": int(episodes), "grid": GRIDS[task],
            "points": results, "best": results[best]}


def _within_design(first: int, last: int) -> bool:
    from apps.eval_tasks import DESIGN_SEEDS

    return any(a <= first and last <= b for a, b in DESIGN_SEEDS)


def ranking(result: dict, top: int = 8) -> str:
    """The best ``top`` points as a text table."""
    order = sorted(result["points"], key=lambda p: (-p["success_rate"], p["median_reaction_s"] or float("inf")))
    lines = [f"deaf search, {result['task']}: {len(result['points'])} points x {result['episodes']} design seeds "
             f"from {result['seed']}", f"{'success':>8} {'95 % CI':>11} {'reaction':>9}  parameters"]
    for p in order[:top]:
        ci = p["success_rate_ci95"]
        reaction = "-" if p["median_reaction_s"] is None else f"{p['median_reaction_s']:.2f} s"
        lines.append(f"{p['success_rate']:>8.2f} {ci[0]:>5.2f}-{ci[1]:<5.2f} {reaction:>9}  "
                     + ", ".join(f"{k}={v}" for k, v in p["params"].items()))
    return "\n".join(lines)


def add_parsers(sub) -> None:
    """Add ``deaf-search`` to the ``acoustic-sim`` subcommands."""
    p = sub.add_parser(
        "deaf-search",
        help="search the deaf baseline's open-loop parameters on design seeds",
        description="Runs the deaf policy (never listening: push the lever at a speed to a felt detent or an angle, hold, "
        "let go; or scan the room at a rate, in jumps with stops to look) at every point of the task's parameter grid on "
        "the same design seeds, and prints the best points; writes OUT/deaf_search.json. The winners are the deaf policy's defaults "
        "(policies/deaf.py). The percept is never read, so the fast auditory models are used.",
    )
    p.add_argument("task", choices=tuple(GRIDS), help="which task")
    p.add_argument("--episodes", type=int, default=DEFAULT_EPISODES,
                   help=f"design seeds per grid point (default {DEFAULT_EPISODES})")
    p.add_argument("--seed", type=int, default=100, help="first design seed (default 100)")
    p.add_argument("--out", type=Path, required=True, help="output folder for deaf_search.json")
    p.set_defaults(func=cmd_deaf_search)


def cmd_deaf_search(args) -> int:
    out = check_writable_folder(args.out, what="--out")
    result = search(args.task, episodes=args.episodes, seed=args.seed)
    write_text(out / "deaf_search.json", json.dumps(result, indent=1) + "\n")
    print(ranking(result))
    print(f"wrote {out / 'deaf_search.json'}")
    return 0


__all__ = ["DEFAULT_EPISODES", "GRIDS", "add_parsers", "grid_points", "ranking", "search"]
