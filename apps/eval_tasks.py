"""What hearing the direction is worth: every task with every policy (``acoustic-sim eval tasks``).

For each task (ReverseAlarm, ParkingBrake, CallResponse) and each policy (``scripted``: the
paper's behaviours from the percepts; ``oracle``: the same behaviours from the ground truth,
the upper bound; ``blind``: the classes without their directions), ``episodes`` seeded
episodes (episode ``i`` uses seed ``seed + i``, the same seeds for every policy), run by
:func:`apps.runner.run_episodes`. Writes ``DIR/<task>/<policy>/episodes.json`` (every
record), ``DIR/tasks.json`` (the summaries, and each target with its result and verdict:
:func:`targets`), ``DIR/REPORT.md`` (the tables) and
``DIR/tasks.png`` (the same as bar charts). The README's "Task results" section is the table
and the figure, copied by ``acoustic-sim eval readme`` between
``<!-- tasks:begin -->`` and ``<!-- tasks:end -->``; a test checks that it agrees with the
committed ``results/tasks``.
"""

from __future__ import annotations

import json
from pathlib import Path

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import atomic_path, write_text
from policies.learned import PREFIX as LEARNED

POLICIES = ("scripted", "oracle", "blind", "deaf", "random")
"""The policies compared by default, in the table's order: what the percept is worth is
scripted minus deaf, what its directions are worth scripted minus blind."""

DEAF_MAX = 0.35
"""Target: the deaf policy's success rate in every task (hearing decides)."""

ORACLE_MIN = 0.98
"""Target: the oracle's success rate in every task (the task can be done)."""

BEGIN, END = "<!-- tasks:begin -->", "<!-- tasks:end -->"

EPISODES = 100
"""Episodes per task and policy of a full run (``--quick``: 3, fast models)."""

DESIGN_SEEDS = ((100, 299), (1000, 1099), (2000, 2099))
"""Episode seed ranges (first, last) on which the policies and the tasks' pipeline settings
were chosen or compared: the one list of them (the report and ``--help`` print it through
:func:`design_seeds_text`)."""

EVAL_SEED = 3000
"""Seed of a run's first episode by default: held-out episodes (3000-3099 in a full run),
outside every :data:`DESIGN_SEEDS` range, so that the report measures the choices on
episodes none of them looked at. How the ranges grew: docs/notes/design_seeds.md."""


def design_seeds_text() -> str:
    """The design seed ranges in words, ``first-last`` each, joined by commas and a final "and"."""
    ranges = [f"{a}-{b}" for a, b in DESIGN_SEEDS]
    return ranges[0] if len(ranges) == 1 else ", ".join(ranges[:-1]) + " and " + ranges[-1]


def held_out(first: int, last: int) -> bool:
    """Whether the seeds ``first``..``last`` avoid every design seed range."""
    return all(last < a or first > b for a, b in DESIGN_SEEDS)




def _runs_on(policy: str, task: str) -> bool:
    """Whether ``eval tasks`` runs ``policy`` on ``task``: a learned one on its own task only."""
    if not policy.startswith(LEARNED):
        return True
    from policies.learned import load_metadata

    return load_metadata(policy[len(LEARNED):])["task"] == task


def run_tasks(*, out, profile: str = "paper", episodes: int | None = None, seed: int = EVAL_SEED, quick: bool = False,
              progress: bool = True, policies=None) -> dict:
    """Run every task with every policy; returns what ``tasks.json`` holds.

    Parameters
    ----------
    out : path-like
        Output folder (created).
    profile : str
        Auditory models, ``paper`` or ``fast`` (``quick`` forces ``fast``).
    episodes : int, optional
        Per task and policy; default :data:`EPISODES` (3 when ``quick``).
    seed : int
        Seed of the first episode, >= 0 (default :data:`EVAL_SEED`: held out from every design choice).
    quick : bool
        Few episodes with the fast models (tests).
    policies : sequence of str, optional
        Policy names or ``module:Class`` (:func:`policies.policy_class`); default :data:`POLICIES`.
    """
    from policies import policy_class
    from acoustic_sim.experiments.report import write_json
    from apps.runner import TASK_NAMES, run_episodes

    if quick:
        profile = "fast"
    episodes = (3 if quick else EPISODES) if episodes is None else episodes
    policies = tuple(dict.fromkeys(POLICIES if policies is None else policies))
    plan = [(task, policy) for task in TASK_NAMES for policy in policies if _runs_on(policy, task)]
    for task, policy in plan:  # every policy known before the first episode runs
        policy_class(policy, task)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for task, policy in plan:
        folder = out / task / ("learned" if policy.startswith(LEARNED) else policy.replace(":", "."))
        result = run_episodes(task, policy, episodes, seed, folder, profile=profile, progress=progress)
        s = result["summary"]
        rows.append({"task": task, "policy": "learned" if policy.startswith(LEARNED) else policy,
                     "episodes": len(result["records"]),
                     **{k: s[k] for k in ("success_rate", "success_rate_ci95", "false_release_rate",
                                          "false_release_rate_ci95", "median_reaction_s", "outcomes")}})
    data = {"profile": profile, "seed": int(seed), "episodes": int(episodes), "quick": bool(quick),
            "policies": list(policies), "rows": rows}
    data["targets"] = targets(data)
    write_json(out / "tasks.json", data)
    report(out)
    return data


def report(out) -> Path:
    """Write ``out/REPORT.md`` and ``out/tasks.png`` from a finished run's ``tasks.json``."""
    out = Path(out)
    figure(out)
    path = out / "REPORT.md"
    write_text(path, "# Task results\n\n" + table(out) + f"\n\n![tasks]({FIGURE})\n")
    return path


FIGURE = "tasks.png"
"""The run's figure, next to ``tasks.json``."""


def figure(out) -> Path:
    """Bar charts of a finished run (success, false releases, median reaction per task and
    policy), written to ``out/tasks.png`` from ``tasks.json``; returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    out = Path(out)
    data = _load(out)
    task_names = list(dict.fromkeys(r["task"] for r in data["rows"]))
    cell = {(r["task"], r["policy"]): r for r in data["rows"]}
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.2))
    x = np.arange(len(task_names))
    policies = list(dict.fromkeys(r["policy"] for r in data["rows"]))  # a learned row runs on its own task only
    empty: dict = {}
    width = 0.8 / len(policies)
    panels = (("success_rate", "success rate", (0, 1.05)), ("false_release_rate", "false-release rate", (0, 1.05)),
              ("median_reaction_s", "median reaction (s)", None))
    for ax, (key, label, ylim) in zip(axes, panels):
        for i, policy in enumerate(policies):
            vals = [cell.get((t, policy), empty).get(key) for t in task_names]
            cis = [cell.get((t, policy), empty).get(f"{key}_ci95") for t in task_names]
            err = None
            if any(c is not None for c in cis):  # the 95 % interval of a rate
                err = np.array([[np.nan, np.nan] if c is None or v is None else [v - c[0], c[1] - v]
                                for v, c in zip(vals, cis)]).T
            bars = ax.bar(x + (i - (len(policies) - 1) / 2) * width, [np.nan if v is None else v for v in vals],
                          width=width, label=policy, yerr=err, error_kw={"elinewidth": 0.7, "capsize": 1.5})
            for b, v, c in zip(bars, vals, cis):
                top = 0 if v is None else (v if c is None else c[1])  # above the interval's bar
                ax.annotate("n/a" if v is None else f"{v:.2f}", (b.get_x() + b.get_width() / 2, top),
                            ha="center", va="bottom", fontsize=6)
        ax.set_xticks(x, task_names, fontsize=8)
        ax.set_title(label, fontsize=9)
        if ylim:
            ax.set_ylim(*ylim)
        else:
            ax.set_ylim(0, ax.get_ylim()[1] * 1.08)
    axes[1].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Tasks, {data['episodes']} episodes per policy ({data['profile']} models; bars: 95 % intervals "
                 "of the rates)", fontsize=10)
    fig.tight_layout()
    path = out / FIGURE
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path


def _load(out: Path) -> dict:
    path = Path(out) / "tasks.json"
    if not path.is_file():
        raise ConfigError(f"{path} is missing: run `acoustic-sim eval tasks --out {out}` first")
    return json.loads(path.read_text())


def _rate(v, ci=None) -> str:
    if v is None:
        return "n/a"
    return f"{v:.2f}" + ("" if ci is None else f" ({ci[0]:.2f}-{ci[1]:.2f})")


SUCCESS_MIN = 0.9
"""Target: the scripted policy's success rate in every task."""

REACTION_MAX_S = {"reverse-alarm": 0.5, "parking-brake": 0.3}
"""Target: the scripted policy's median reaction in the cabin tasks (s; in the room a success
is a look at the caller within the response window, 1.5 s)."""

WHY = {
    "reverse-alarm": "`policies.scripted.ScriptedReverseAlarm`",
    "parking-brake": "`policies.scripted.ScriptedParkingBrake`",
    "call-response": "docs/notes/call_response.md",
}
"""Where each task's misses are written down."""


def targets(data: dict) -> list[dict]:
    """The task targets for a run's summaries, each ``{"task", "target", "result", "met"}``:
    the scripted policy's success rate, false releases (none, in the cabin) and median reaction,
    and the blind policy's false releases (the distractors must bite: the lower end of its
    rate's 95 % interval above 0)."""
    rows = {(r["task"], r["policy"]): r for r in data["rows"]}
    out = []
    for task in dict.fromkeys(r["task"] for r in data["rows"]):
        d, o = rows.get((task, "deaf")), rows.get((task, "oracle"))
        if d is not None:
            out.append({"task": task, "target": f"deaf: success at most {DEAF_MAX}",
                        "result": _rate(d["success_rate"], d.get("success_rate_ci95")), "met": d["success_rate"] <= DEAF_MAX})
        if o is not None:
            out.append({"task": task, "target": f"oracle: success at least {ORACLE_MIN}",
                        "result": _rate(o["success_rate"], o.get("success_rate_ci95")), "met": o["success_rate"] >= ORACLE_MIN})
        s = rows.get((task, "scripted"))
        if s is None:
            continue
        what = "success (the caller looked at within 1.5 s)" if task == "call-response" else "success"
        out.append({"task": task, "target": f"scripted: {what} at least {SUCCESS_MIN}",
                    "result": _rate(s["success_rate"], s.get("success_rate_ci95")), "met": s["success_rate"] >= SUCCESS_MIN})
        limit = REACTION_MAX_S.get(task)
        if limit is not None:
            react = s["median_reaction_s"]
            out.append({"task": task, "target": f"scripted: median reaction at most {limit:g} s",
                        "result": "n/a" if react is None else f"{react:.2f} s", "met": react is not None and react <= limit})
        if task == "call-response":
            continue
        out.append({"task": task, "target": "scripted: no false release",
                    "result": _rate(s["false_release_rate"], s.get("false_release_rate_ci95")),
                    "met": s["false_release_rate"] == 0.0})
        b = rows.get((task, "blind"))
        if b is not None:
            lo = (b.get("false_release_rate_ci95") or [b["false_release_rate"]])[0]
            out.append({"task": task, "target": "blind: false releases well above 0 (interval above 0)",
                        "result": _rate(b["false_release_rate"], b.get("false_release_rate_ci95")), "met": lo > 0.0})
    return out


def _target_lines(data: dict) -> list[str]:
    rows = data.get("targets") or targets(data)  # the run's own targets, as it measured them
    lines = ["**Against the targets** (this run's models; the headless tests check the same targets with the `fast` "
             "models over 20 episodes, `tests/test_policies.py`):", "", "| task | target | result | met |", "|---|---|---|---|"]
    lines += [f"| {r['task']} | {r['target']} | {r['result']} | {'yes' if r['met'] else 'no'} |" for r in rows]
    missed = list(dict.fromkeys(r["task"] for r in rows if not r["met"]))
    if missed:
        lines += ["", "Where the episodes that miss fail, and what was tried: "
                  + ", ".join(WHY.get(t, t) for t in missed) + "."]
    return lines + [""]


def table(out) -> str:
    """The Markdown tables of a finished run (REPORT.md's body and the README section): the
    targets, then every task and policy."""
    data = _load(out)
    first, last = data["seed"], data["seed"] + data["episodes"] - 1
    seeds = (f"held out: the policies were tuned on seeds {design_seeds_text()}" if held_out(first, last) else
             f"overlapping seeds {design_seeds_text()}, on which the policies were tuned: an optimistic measure")
    lines = [
        *_target_lines(data),
        f"{data['episodes']} episodes per task and policy (seeds {first}-{last}, {seeds}; "
        f"`{data['profile']}` models). Reaction: from the sound's start to letting go (the cabin) or to the "
        "person in view (the room). A false release lets go on a distractor. In brackets: the rate's 95 % "
        "interval (Wilson; the episodes are a sample of the task's random draws).",
        "",
        "| task | policy | success | false releases | median reaction (s) | outcomes |",
        "|---|---|---|---|---|---|",
    ]
    for r in data["rows"]:
        outcomes = ", ".join(f"{k} {v}" for k, v in sorted(r["outcomes"].items()))
        react = "n/a" if r["median_reaction_s"] is None else f"{r['median_reaction_s']:.2f}"
        lines.append(f"| {r['task']} | {r['policy']} | {_rate(r['success_rate'], r.get('success_rate_ci95'))} "
                     f"| {_rate(r['false_release_rate'], r.get('false_release_rate_ci95'))} "
                     f"| {react} | {outcomes} |")
    return "\n".join(lines)


def readme_section(results_dir, image_prefix: str = "results/tasks") -> str:
    """The README's generated "Task results" section: the table and the figure."""
    return "\n".join([BEGIN, table(results_dir), "", f"![tasks]({image_prefix}/{FIGURE})", END])


def update_readme(readme, results_dir, image_prefix: str = "results/tasks") -> bool:
    """Replace the README's task section; returns True when the file changed."""
    from acoustic_sim.experiments.report import replace_section

    return replace_section(readme, BEGIN, END, readme_section(results_dir, image_prefix))


__all__ = ["BEGIN", "END", "EPISODES", "FIGURE", "POLICIES", "figure", "readme_section", "report", "run_tasks", "table",
           "targets", "update_readme"]
