"""The README's paper section is generated from the committed results/paper run, never typed."""

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
