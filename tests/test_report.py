"""The README's paper section is generated from the committed results/paper run, never typed."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from acoustic_sim.errors import ConfigError
from acoustic_sim.experiments.report import BEGIN, END, readme_section, update_readme

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "paper"


def test_readme_section_is_the_committed_run():
    text = (ROOT / "README.md").read_text()
    assert text.count(BEGIN) == 1 and text.count(END) == 1
    section = text[text.index(BEGIN) : text.index(END) + len(END)]
    assert section == readme_section(RESULTS, "results/paper"), "README is stale: run `acoustic-sim eval readme`"
    for line in section.splitlines():
        if line.startswith("!["):
            assert (ROOT / line[line.index("(") + 1 : line.index(")")]).is_file(), line


def test_update_readme_replaces_only_its_section(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"# title\n\nbefore\n\n{BEGIN}\nold numbers 1 2 3\n{END}\n\nafter\n")
    assert update_readme(readme, RESULTS, image_prefix="results/paper")
    text = readme.read_text()
    assert text.startswith("# title\n\nbefore\n\n") and text.endswith("\n\nafter\n")
    assert "old numbers" not in text and "| white_noise |" in text
    assert not update_readme(readme, RESULTS, image_prefix="results/paper")  # idempotent
    readme.write_text("no markers here\n")
    with pytest.raises(ConfigError, match="paper:begin"):
        update_readme(readme, RESULTS)


def test_eval_readme_command(tmp_path):
    exe = [sys.executable, "-m", "acoustic_sim.cli"]
    readme = tmp_path / "README.md"
    readme.write_text(f"{BEGIN}\n{END}\n")
    results = tmp_path / "run"
    shutil.copytree(RESULTS, results, ignore=shutil.ignore_patterns("*.sofa", "*.png"))
    ok = subprocess.run([*exe, "eval", "readme", "--results", str(results), "--readme", str(readme)],
                        capture_output=True, text=True, cwd=tmp_path)
    assert ok.returncode == 0, ok.stderr
    assert "updated from" in ok.stdout and "| sawtooth | 2000 |" in readme.read_text()
    for args, match in (
        (["--results", str(tmp_path / "none")], "no finished eval paper run"),
        (["--results", str(results), "--readme", str(tmp_path / "missing.md")], "no such file"),
    ):
        bad = subprocess.run([*exe, "eval", "readme", *args], capture_output=True, text=True, cwd=tmp_path)
        assert bad.returncode != 0 and match in bad.stderr and "Traceback" not in bad.stderr, bad.stderr


def test_targets_table_is_computed_from_the_run():
    """Each target's verdict follows the numbers: met, missed, or met by one room estimator only."""
    from acoustic_sim.experiments.report import targets

    def run(square_2k, tb_frames, tb_wavefront, f1):
        sim = [{"signal": s, "f0_hz": f, "ssdenet_deg": 5.0, "music_deg": 9.0}
               for s, f in (("sine", 500.0), ("square", 500.0), ("sawtooth", 2000.0), ("white_noise", None))]
        sim.append({"signal": "square", "f0_hz": 2000.0, "ssdenet_deg": square_2k, "music_deg": 30.0})
        room = {"lr_accuracy": {"ssdenet": 1.0, "music": 0.5, "ssdenet-wavefront": 0.98},
                "tb_accuracy": {"ssdenet": tb_frames, "music": 0.99, "ssdenet-wavefront": tb_wavefront}}
        return targets({"simulation": sim, "room": room}, {"f1_macro": f1})

    good = run(14.9, 0.85, 0.9, 0.90)
    assert [r["experiment"] for r in good] == ["simulation", "simulation", "room", "room", "detection"]
    assert "top-bottom" in good[3]["target"]
    assert all(r["met"] is True for r in good), good
    bad = run(20.8, 0.72, 0.87, 0.89)
    assert [r["met"] for r in bad] == [True, False, True, True, False], bad
    assert bad[3]["met_by"] == ["first wavefront"] and good[3]["met_by"] == ["on the frames", "first wavefront"]
    assert bad[1]["result"] == "over: square 2000 Hz 20.8 deg"
    assert bad[3]["result"] == "on the frames 0.720, first wavefront 0.870"
    assert run(14.0, 0.5, 0.5, 0.95)[3]["met"] is False
    # SSDENet above MUSIC on one signal: that target is missed.
    assert run(31.0, 0.9, 0.9, 0.95)[0]["met"] is False


# -- the task results section (acoustic-sim eval tasks) ---------------------------------------------

TASKS = ROOT / "results" / "tasks"


def test_readme_task_section_is_the_committed_run():
    import json

    from apps import eval_tasks as tasks
    from apps.runner import TASK_NAMES

    text = (ROOT / "README.md").read_text()
    assert text.count(tasks.BEGIN) == 1 and text.count(tasks.END) == 1
    section = text[text.index(tasks.BEGIN) : text.index(tasks.END) + len(tasks.END)]
    assert section == tasks.readme_section(TASKS), "README is stale: run `acoustic-sim eval readme`"
    data = json.loads((TASKS / "tasks.json").read_text())
    assert data["profile"] == "paper" and not data["quick"] and data["episodes"] >= 20  # a full run
    # On held-out episodes: none of the seeds on which the policies were tuned.
    first, last = data["seed"], data["seed"] + data["episodes"] - 1
    assert all(last < a or first > b for a, b in tasks.DESIGN_SEEDS)
    assert f"held out: the policies were tuned on seeds {tasks.design_seeds_text()}" in section
    # Every task with each of the run's policies (the committed run predates the deaf and random
    # rows, and lists no "policies": its three are scripted, oracle and blind).
    policies = data.get("policies", ["scripted", "oracle", "blind"])
    assert {"scripted", "oracle", "blind"} <= set(policies)
    assert [(r["task"], r["policy"]) for r in data["rows"]] == [(t, p) for t in TASK_NAMES for p in policies]
    for r in data["rows"]:
        assert (TASKS / r["task"] / r["policy"] / "episodes.json").is_file()
    assert (TASKS / "tasks.png").is_file() and "![tasks](results/tasks/tasks.png)" in section


def test_eval_tasks_runs_every_task_with_every_policy(tmp_path):
    from apps import eval_tasks as tasks
    from apps.runner import TASK_NAMES

    data = tasks.run_tasks(out=tmp_path, quick=True, episodes=1, progress=False)
    assert data["profile"] == "fast" and data["episodes"] == 1 and data["seed"] == tasks.EVAL_SEED
    # per cabin task: deaf, oracle, scripted success, reaction, no false release, blind; the room: three
    assert data["targets"] == tasks.targets(data) and len(data["targets"]) == 15
    assert [(r["task"], r["policy"]) for r in data["rows"]] == [(t, p) for t in TASK_NAMES for p in tasks.POLICIES]
    for r in data["rows"]:
        assert r["episodes"] == 1 and r["success_rate"] in (0.0, 1.0) and sum(r["outcomes"].values()) == 1
        assert r["success_rate_ci95"][0] <= r["success_rate"] <= r["success_rate_ci95"][1]
        assert (tmp_path / r["task"] / r["policy"] / "episodes.json").is_file()
    table = tasks.table(tmp_path)
    # The targets table (header and 15 targets), then the results (header and one row per task and policy).
    assert table.count("\n| ") == (1 + 15) + (1 + 15) and "| call-response | blind |" in table
    assert "| reverse-alarm | deaf: success at most 0.35 |" in table
    assert "| parking-brake | blind: false releases" in table
    assert (tmp_path / "REPORT.md").read_text().endswith(table + "\n\n![tasks](tasks.png)\n")
    assert (tmp_path / "tasks.png").stat().st_size > 10_000
    readme = tmp_path / "README.md"
    readme.write_text(f"# t\n\n{tasks.BEGIN}\nold\n{tasks.END}\n\nafter\n")
    assert tasks.update_readme(readme, tmp_path) and not tasks.update_readme(readme, tmp_path)
    assert readme.read_text().endswith("\n\nafter\n") and "old" not in readme.read_text()
    readme.write_text("no markers\n")
    with pytest.raises(ConfigError, match="tasks:begin"):
        tasks.update_readme(readme, tmp_path)
    with pytest.raises(ConfigError, match="eval tasks"):
        tasks.table(tmp_path / "nothing")
    # A run on the seeds the policies were tuned on says so.
    assert "held out" in table and "optimistic" not in table
    path = tmp_path / "tasks.json"
    path.write_text(json.dumps({**json.loads(path.read_text()), "seed": tasks.DESIGN_SEEDS[1][1]}))
    assert "on which the policies were tuned: an optimistic measure" in tasks.table(tmp_path)
    bad = subprocess.run([sys.executable, "-m", "acoustic_sim.cli", "eval", "tasks", "--out", str(tmp_path / "x"),
                          "--episodes", "0"], capture_output=True, text=True)
    assert bad.returncode != 0 and "--episodes" in bad.stderr and "Traceback" not in bad.stderr, bad.stderr



def test_eval_tasks_takes_a_policy_class_and_refuses_an_unknown_one_before_running(tmp_path):
    from apps import eval_tasks as tasks
    from apps.runner import TASK_NAMES

    data = tasks.run_tasks(out=tmp_path / "ok", quick=True, episodes=1, progress=False,
                           policies=["policies.random_policy:RandomHoldPolicy", "deaf"])
    assert [(r["task"], r["policy"]) for r in data["rows"]] == [
        (t, p) for t in TASK_NAMES for p in ("policies.random_policy:RandomHoldPolicy", "deaf")]
    assert (tmp_path / "ok" / "call-response" / "policies.random_policy.RandomHoldPolicy" / "episodes.json").is_file()
    with pytest.raises(ConfigError, match="unknown policy 'psychic'"):
        tasks.run_tasks(out=tmp_path / "bad", quick=True, episodes=1, progress=False, policies=["scripted", "psychic"])
    assert not (tmp_path / "bad").exists()

def test_task_targets_follow_the_summaries():
    """The task targets table: success, reaction, no false release for scripted; blind's
    false releases must have an interval above 0."""
    from apps.eval_tasks import targets

    def row(task, policy, success, fr, fr_ci, react):
        return {"task": task, "policy": policy, "success_rate": success, "success_rate_ci95": None,
                "false_release_rate": fr, "false_release_rate_ci95": fr_ci, "median_reaction_s": react}

    data = {"rows": [
        row("reverse-alarm", "scripted", 0.9, 0.0, [0.0, 0.04], 0.5),
        row("reverse-alarm", "blind", 0.7, 0.3, [0.2, 0.4], 0.1),
        row("parking-brake", "scripted", 0.89, 0.01, [0.0, 0.05], 0.31),
        row("parking-brake", "blind", 0.95, 0.02, [0.0, 0.07], 0.1),
        row("call-response", "scripted", 1.0, 0.0, None, 12.0),
    ]}
    got = [(r["task"], r["target"].split(":")[0], r["met"]) for r in targets(data)]
    assert got == [
        ("reverse-alarm", "scripted", True), ("reverse-alarm", "scripted", True), ("reverse-alarm", "scripted", True),
        ("reverse-alarm", "blind", True),
        ("parking-brake", "scripted", False), ("parking-brake", "scripted", False), ("parking-brake", "scripted", False),
        ("parking-brake", "blind", False),
        ("call-response", "scripted", True),
    ], got
