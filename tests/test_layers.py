"""The package layers: the library below the apps, no import path edits.

``acoustic_sim`` is the library; ``tasks`` (the Gymnasium envs), ``policies`` and ``apps`` (the
episode runner, the demo, the task evaluation) are built on it. Only the command-line entry
(``acoustic_sim/cli.py`` and its ``cli_*.py`` parts) may reach up, so that the library can be
used, tested and replaced without the apps. Every package is installed, so no module needs to
edit ``sys.path``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
APPS = {"apps", "tasks", "policies"}


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, top-level module) of every import in a file, lazy ones inside functions included."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name.split(".")[0]) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module.split(".")[0]))
    return found


def _library_files():
    return sorted(p for p in (ROOT / "acoustic_sim").rglob("*.py") if not p.name.startswith("cli"))


def test_the_library_imports_no_app():
    upward = [f"{p.relative_to(ROOT)}:{line} imports {mod}"
              for p in _library_files() for line, mod in _imports(p) if mod in APPS]
    assert not upward, "\n".join(upward)


def test_tasks_and_policies_do_not_import_the_apps():
    upward = [f"{p.relative_to(ROOT)}:{line} imports {mod}"
              for pkg in ("tasks", "policies") for p in sorted((ROOT / pkg).rglob("*.py"))
              for line, mod in _imports(p) if mod == "apps"]
    assert not upward, "\n".join(upward)


@pytest.mark.parametrize("package", ["acoustic_sim", "apps", "tasks", "policies", "benchmarks", "tests", "scripts"])
def test_no_module_edits_the_import_path(package):
    edits = []
    for p in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text(), filename=str(p))):
            if (isinstance(node, ast.Attribute) and node.attr == "path" and isinstance(node.value, ast.Name)
                    and node.value.id == "sys"):
                edits.append(f"{p.relative_to(ROOT)}:{node.lineno}")
    assert not edits, "sys.path used at " + ", ".join(edits)


def test_the_checker_sees_an_upward_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from policies import make_policy\n    import sys\n    sys.path.insert(0, '.')\n")
    assert (2, "policies") in _imports(bad)


def test_module_names_are_distinct():
    """One name, one module: a traceback or an import reads unambiguously (packages'
    ``__init__.py`` aside)."""
    seen: dict[str, list[str]] = {}
    for top in ("acoustic_sim", "apps", "tasks", "policies", "benchmarks"):
        for p in (ROOT / top).rglob("*.py"):
            if p.name != "__init__.py":
                seen.setdefault(p.name, []).append(str(p.relative_to(ROOT)))
    assert {n: ps for n, ps in seen.items() if len(ps) > 1} == {}
