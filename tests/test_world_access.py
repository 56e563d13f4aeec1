"""One writer and one reader of ``MjData``: ``world/actuation`` writes it, ``world/view`` reads it.

An ``ast`` walk over the source tree (``acoustic_sim``, ``tasks``, ``policies``, ``apps``,
``benchmarks``, ``scripts``) fails, naming file:line, on any access to MuJoCo's simulation
state elsewhere. ``MjModel`` reads (names, ids, sizes, ``model.key_qpos``, ``model.eq_data``)
are fine anywhere. The rule, made precise:

1. an attribute that only ``MjData`` has (``qpos``, ``ctrl``, ``site_xpos``, ``eq_active``, ...,
   taken from MuJoCo itself: ``dir(MjData)`` less ``dir(MjModel)``), on any object, except the
   few such names too common to mean MuJoCo (:data:`AMBIGUOUS_FIELDS`, e.g. ``time``);
2. any ``MjData`` attribute, those included, on a *data object*: an expression named ``data``,
   ``d`` or ``_data``, or a name the file binds to ``mujoco.MjData(...)`` or annotates as
   ``MjData``;
3. a named accessor (``data.joint(...)``, ``data.actuator(...)``, ``data.body(...)``,
   ``data.site(...)``, ...) called on a data object (on a model, the same accessors are model reads);
4. a ``mujoco`` function whose signature takes an ``MjData`` (``mj_step``, ``mj_forward``,
   ``mj_kinematics``, ``mj_jacSite``, ``mj_ray``, ...; read from MuJoCo's docstrings, so
   ``mj_name2id`` and the other model-only functions pass), or ``Renderer.update_scene``
   (which reads the data to draw it);
5. a write into ``model.eq_data``: the grasp's anchor, part of acting on the world.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import mujoco
import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCE_DIRS = ("acoustic_sim", "tasks", "policies", "apps", "benchmarks", "scripts")
OWNERS = ("acoustic_sim/world/actuation", "acoustic_sim/world/view.py")
"""The writer (a module or a package) and the reader of ``MjData``: paths relative to the root."""

AMBIGUOUS_FIELDS = frozenset({
    "M", "act", "contact", "energy", "history", "model", "ne", "nf", "nl", "ncon", "plastic", "solver", "ten",
    "threadpool", "time", "timer", "userdata", "warning", "xaxis",
})
"""``MjData``-only attributes that other objects have too (``time.time``, ``percept.time``,
matplotlib's ``ax.xaxis``): flagged on data objects only."""

ACCESSORS = frozenset({"actuator", "body", "cam", "camera", "geom", "jnt", "joint", "light", "sensor", "site", "tendon",
                       "plugin", "bind", "bind_scalar"})
"""Named accessors that ``MjData`` shares with ``MjModel``: data reads only on a data object."""

DATA_NAMES = frozenset({"data", "d", "_data"})
"""What a data object is called by convention (``self.data``, ``coupling.data``, ``d``)."""

GRASP_MODEL_FIELDS = frozenset({"eq_data"})
"""``MjModel`` fields whose writes act on the world (the grasp anchor)."""


@functools.cache
def data_fields() -> frozenset[str]:
    """Attributes of ``MjData`` that ``MjModel`` lacks (the simulation state)."""
    model = mujoco.MjModel.from_xml_string("<mujoco/>")
    data = mujoco.MjData(model)
    return frozenset(a for a in dir(data) if not a.startswith("_")) - {a for a in dir(model) if not a.startswith("_")}


@functools.cache
def data_functions() -> frozenset[str]:
    """``mujoco`` functions whose signature (the docstring's first line) takes an ``MjData``."""
    out = set()
    for name in dir(mujoco):
        f = getattr(mujoco, name)
        if callable(f) and not isinstance(f, type) and "MjData" in (f.__doc__ or "").split("\n", 1)[0]:
            out.add(name)
    return frozenset(out)


def _terminal(node: ast.AST) -> str | None:
    """The last name of ``a.b.c`` or ``c``; None for other expressions."""
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.Name):
        return node.id
    return None


def _is_mjdata_annotation(node: ast.AST | None) -> bool:
    return node is not None and any(_terminal(n) == "MjData" for n in ast.walk(node))


def _is_mjdata_call(node: ast.AST | None) -> bool:
    return isinstance(node, ast.Call) and _terminal(node.func) == "MjData"


class _Checker(ast.NodeVisitor):
    def __init__(self, tree: ast.AST) -> None:
        self.found: list[tuple[int, str]] = []
        self.data_names = set(DATA_NAMES)
        self.mujoco_modules = {"mujoco"}
        self.mujoco_functions: set[str] = set()  # local names of data functions imported from mujoco
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                self.mujoco_modules |= {a.asname for a in node.names if a.name == "mujoco" and a.asname}
            elif isinstance(node, ast.ImportFrom) and node.module == "mujoco":
                self.mujoco_functions |= {a.asname or a.name for a in node.names if a.name in data_functions()}
            elif isinstance(node, ast.Assign) and _is_mjdata_call(node.value):
                self.data_names |= {_terminal(t) for t in node.targets} - {None}
            elif isinstance(node, ast.AnnAssign) and (_is_mjdata_annotation(node.annotation) or _is_mjdata_call(node.value)):
                self.data_names |= {_terminal(node.target)} - {None}
            elif isinstance(node, ast.arg) and _is_mjdata_annotation(node.annotation):
                self.data_names.add(node.arg)

    def _flag(self, node: ast.AST, what: str) -> None:
        self.found.append((node.lineno, what))

    def _is_data(self, node: ast.AST) -> bool:
        return _terminal(node) in self.data_names

    def visit_Attribute(self, node: ast.Attribute) -> None:
        fields = data_fields()
        if node.attr in fields and (node.attr not in AMBIGUOUS_FIELDS or self._is_data(node.value)):
            self._flag(node, f"MjData field .{node.attr}")
        self.generic_visit(node)

    def visit_Call(self, node: ast.Call) -> None:
        f = node.func
        if isinstance(f, ast.Attribute):
            if f.attr in ACCESSORS and self._is_data(f.value):
                self._flag(node, f"MjData accessor .{f.attr}()")
            elif f.attr in data_functions() and isinstance(f.value, ast.Name) and f.value.id in self.mujoco_modules:
                self._flag(node, f"mujoco.{f.attr}() on MjData")
            elif f.attr == "update_scene":
                self._flag(node, "Renderer.update_scene() reads MjData")
        elif isinstance(f, ast.Name) and f.id in self.mujoco_functions:
            self._flag(node, f"mujoco.{f.id}() on MjData")
        self.generic_visit(node)

    def _check_target(self, target: ast.AST) -> None:
        for n in ast.walk(target):
            if isinstance(n, ast.Attribute) and n.attr in GRASP_MODEL_FIELDS:
                self._flag(n, f"write into MjModel.{n.attr} (the grasp)")

    def visit_Assign(self, node: ast.Assign) -> None:
        for t in node.targets:
            self._check_target(t)
        self.generic_visit(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        self._check_target(node.target)
        self.generic_visit(node)


def violations(source: str, filename: str = "<snippet>") -> list[str]:
    """``file:line: what`` for every access to ``MjData`` in ``source`` (rules 1-5 above)."""
    tree = ast.parse(source, filename=filename)
    checker = _Checker(tree)
    checker.visit(tree)
    return [f"{filename}:{line}: {what}" for line, what in sorted(set(checker.found))]


def _source_files() -> list[Path]:
    files = []
    for folder in SOURCE_DIRS:
        files += sorted((ROOT / folder).rglob("*.py"))
    return files


def _owned(rel: str) -> bool:
    return any(rel == o or rel.startswith(o + "/") or rel == o + ".py" for o in OWNERS)


def test_only_actuation_and_view_touch_mjdata():
    found = []
    for path in _source_files():
        rel = path.relative_to(ROOT).as_posix()
        if not _owned(rel):
            found += violations(path.read_text(encoding="utf-8"), rel)
    assert not found, "MjData accessed outside world/actuation and world/view:\n" + "\n".join(found)


def test_the_owners_exist():
    # A stale entry would exempt whatever file takes its name later: OWNERS names real files.
    for owner in OWNERS:
        assert (ROOT / owner).exists() or (ROOT / (owner + ".py")).exists(), owner


@pytest.mark.parametrize(("snippet", "what"), [
    ("data.ctrl[3] = 0.5", "MjData field .ctrl"),
    ("x = env.unwrapped.data.qpos[0]", "MjData field .qpos"),
    ("p = thing.site_xpos[2]", "MjData field .site_xpos"),
    ("t = self._data.time", "MjData field .time"),
    ("q = data.joint('robot/neck_yaw').qpos[0]", "MjData accessor .joint()"),
    ("d.actuator(name).ctrl[0] = 1.0", "MjData accessor .actuator()"),
    ("import mujoco\nmujoco.mj_step(m, d)", "mujoco.mj_step() on MjData"),
    ("import mujoco as mj\nmj.mj_ray(m, d, p, v, None, 1, -1, g)", "mujoco.mj_ray() on MjData"),
    ("from mujoco import mj_forward\nmj_forward(m, d)", "mujoco.mj_forward() on MjData"),
    ("import mujoco\nscratch = mujoco.MjData(model)\nscratch.contact", "MjData field .contact"),
    ("def f(state: mujoco.MjData):\n    return state.body('x')", "MjData accessor .body()"),
    ("renderer.update_scene(data, camera)", "Renderer.update_scene() reads MjData"),
    ("model.eq_data[eq, 0:3] = anchor", "write into MjModel.eq_data (the grasp)"),
])
def test_the_checker_flags_a_violation(snippet, what):
    found = violations(snippet)
    assert any(f.endswith(what) for f in found), (snippet, found)


@pytest.mark.parametrize("snippet", [
    "import mujoco\ni = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, 'x')",
    "q = model.key_qpos[key, adr]",
    "anchor = model.eq_data[eq, 0:3]",
    "lo, hi = model.actuator(name).ctrlrange",
    "adr = model.joint(name).qposadr[0]",
    "import time\nt = time.time()",
    "t = percept.time",
    "import mujoco\ndata = mujoco.MjData(model)",
    "model.vis.global_.offwidth = 640",
])
def test_the_checker_passes_model_reads(snippet):
    assert violations(snippet) == []
