"""The parts of the tasks' specification docstrings that every task shares, written once.

A task's class docstring is its specification, in the Gymnasium style (Description, Action
Space, Observation Space, Rewards, Starting State, Episode End, Arguments). The action and
observation tables and the arguments common to every task are the same text in each, and a
task family's rewards are written where they are computed; the docstring holds a
placeholder line instead, which :meth:`tasks.base.HearingTaskEnv.__init_subclass__`
expands when the class is created, so ``help(env)`` and ``inspect.getdoc`` show the whole
specification:

========================  =================================================================
placeholder line          expands to
========================  =================================================================
``{spaces_and_rewards}``  the sections Action Space (the robot's joints, then the class's
                          :attr:`~tasks.base.HearingTaskEnv.spec_action_rows` and
                          :attr:`~tasks.base.HearingTaskEnv.spec_action_notes`),
                          Observation Space (proprioception, the class's
                          :attr:`~tasks.base.HearingTaskEnv.spec_observation_rows`, the
                          percept, the optional keys) and Rewards
                          (:attr:`~tasks.base.HearingTaskEnv.spec_rewards`)
``{common_arguments}``    the constructor arguments every task has, one line each
========================  =================================================================
"""

from __future__ import annotations

import re
import textwrap

from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.errors import ConfigError

ROBOT_ACTION_ROWS: tuple[tuple[str, str, str, str], ...] = (
    ("0", "neck_yaw (+ left)", "-90 .. 90", "deg"),
    ("1", "neck_pitch (+ nose down)", "-45 .. 45", "deg"),
    ("2", "eye_yaw (+ left)", "-30 .. 30", "deg"),
    ("3", "eye_pitch", "-25 .. 25", "deg"),
    ("4", "left_shoulder_pitch", "-45 .. 170", "deg"),
    ("5", "left_shoulder_roll", "-15 .. 120", "deg"),
    ("6", "left_shoulder_yaw", "-90 .. 90", "deg"),
    ("7", "left_elbow", "0 .. 145", "deg"),
    ("8", "left_wrist", "-70 .. 70", "deg"),
    ("9-13", "right arm, same joints", "same", "deg"),
)
"""Action table rows (idx, channel, range, unit) of the robot's joints, first in every task."""

PROPRIOCEPTION_ROWS: tuple[tuple[str, str, str], ...] = (
    ("joint_pos", "(14,)", "rad: neck yaw, pitch; eye yaw, pitch; left arm 5; right arm 5"),
    ("joint_vel", "(14,)", "rad/s, same order (clipped to +-50)"),
)
"""Observation table rows (key, shape, meaning) before the task's own."""

PERCEPT_ROWS: tuple[tuple[str, str, str], ...] = (
    ("class_prob", "(6,)", f"the percept's fused class probabilities ({', '.join(SOUND_CLASSES)})"),
    ("class_dir", "(18,)", ("per class, the estimated direction (unit vector, head frame: x forward, y left, "
                            "z up), class k in entries 3k..3k+2; zeros when the class has no estimate")),
    ("class_conf", "(6,)", "per class, the estimate's confidence 0..1 (0: no estimate)"),
    ("tracked_dir", "(18,)", ("per class, the world-frame tracker's direction seen from the head now (unit "
                              "vector, head frame), from every frame heard this episode; zeros before any")),
    ("tracked_conf", "(6,)", "per class, the tracker's posterior mass near its peak 0..1 (0: nothing heard yet)"),
    ("tracked_decided", "(6,)", ("per class, 1 when the tracker has decided front from back (a head turn "
                                 "moved the mirror image away), else 0")),
    ("existence", "(D,)", ("SSDENet existence map of the most likely class that has an estimate, over the D "
                           "(327) grid directions; zeros if none")),
    ("audio", "(2, 706)", "optional (``audio_obs``): the digital ear block, full scale"),
    ("spectra", "(2, 1025)", "optional (``spectra_obs``): |X|^2 of the ear frame, full scale"),
    ("image", "(H, W, 3)", "optional (``image_obs``): the right eye camera, uint8"),
)
"""Observation table rows after the task's own: the percept and the optional keys."""

COMMON_ARGUMENTS = """\
``render_mode`` (str | None, default None): ``"rgb_array"`` for :meth:`render`.
``profile`` (str, default "paper"): auditory models, ``"paper"`` or ``"fast"``.
``hrtf`` (str, default "kemar"): the ears.
``max_episode_s`` (float | None, default None): truncation time in s (None: {max_episode_s:g} s).
``action_mode`` (str, default "joints"): ``"joints"`` or ``"skill"`` (see Action Space).
``reward_mode`` (str, default "sparse"): ``"sparse"`` or ``"shaped"`` (see Rewards).
``audio_obs`` (bool, default False): add ``audio``.
``spectra_obs`` (bool, default False): add ``spectra``.
``image_obs`` (bool, default False): add ``image``.
``image_size`` (tuple, default (120, 160)): (height, width) of ``image``, pixels.
``torch_threads`` (int | None, default 1): torch threads while the pipeline runs."""
"""The arguments of every task, one line each: ``name`` (type, default value): meaning."""

MEANING_WIDTH = 67
"""Characters of the observation table's last column before it wraps."""

PROSE_WIDTH = 92
"""Characters of a line of generated prose."""

_PLACEHOLDER = re.compile(r"^(?P<indent>[ \t]*)\{(?P<name>\w+)\}[ \t]*$", re.MULTILINE)


def rst_table(header: tuple[str, ...], rows, *, wrap_last: int | None = None) -> str:
    """A reStructuredText simple table, columns as wide as their longest cell.

    Parameters
    ----------
    header : tuple of str
    rows : iterable of tuple of str
        One cell per column.
    wrap_last : int, optional
        Wrap the last column's cells at this many characters (continuation lines are
        indented to the column).
    """
    rows = [tuple(str(c) for c in r) for r in rows]
    if any(len(r) != len(header) for r in rows):
        raise ConfigError(f"table rows must have {len(header)} cells: {rows}")
    lines = [(r[:-1], textwrap.wrap(r[-1], wrap_last) if wrap_last else [r[-1]]) for r in [header, *rows]]
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header) - 1)]
    widths.append(max(len(part) for _, parts in lines for part in parts))
    rule = "  ".join("=" * w for w in widths)

    def line(cells) -> str:
        return "  ".join(c.ljust(w) for c, w in zip(cells, widths)).rstrip()

    out = [rule]
    for k, (first, parts) in enumerate(lines):
        out.append(line((*first, parts[0])))
        out.extend(line(("",) * len(first) + (p,)) for p in parts[1:])
        if k == 0:
            out.append(rule)
    out.append(rule)
    return "\n".join(out)


def parts(cls) -> dict[str, str]:
    """The placeholders' texts for a task class (see the module docstring)."""
    n = sum(_channels(idx) for idx, *_ in (*ROBOT_ACTION_ROWS, *cls.spec_action_rows))
    actions = rst_table(("idx", "channel", "range", "unit"), (*ROBOT_ACTION_ROWS, *cls.spec_action_rows))
    notes = ("Joint targets drive position servos (the ranges are the actuators' control ranges); "
             "``env.unwrapped.layout`` converts physical targets to actions.")
    if cls.spec_action_notes:
        notes += " " + cls.spec_action_notes
    observations = rst_table(("key", "shape", "meaning"), (*PROPRIOCEPTION_ROWS, *cls.spec_observation_rows, *PERCEPT_ROWS),
                             wrap_last=MEANING_WIDTH)
    action = (f"``action_mode=\"joints\"``: ``Box(-1, 1, ({n},), float32)``, normalized targets; -1 and +1 are the "
              "ends of the range.")
    action = f"{textwrap.fill(action, PROSE_WIDTH)}\n\n{actions}\n\n{textwrap.fill(notes, PROSE_WIDTH)}"
    rewards = textwrap.fill("``reward_mode=\"sparse\"``: " + cls.spec_rewards, PROSE_WIDTH)
    if cls.skill_rows:
        skill = (f"``action_mode=\"skill\"``: ``Box(-1, 1, ({len(cls.skill_rows)},), float32)``; the zero action keeps "
                 "everything as it is (nothing moves, nothing lets go), the rest of the robot holds its rest pose "
                 "(:mod:`tasks.skills`).")
        table = rst_table(("idx", "component", "range", "meaning"), cls.skill_rows, wrap_last=MEANING_WIDTH)
        action += f"\n\n{textwrap.fill(skill, PROSE_WIDTH)}\n\n{table}"
    if cls.spec_shaped_rewards:
        shaped = ("``reward_mode=\"shaped\"``: the sum of the terms that ``info`` reports each step in both modes: "
                  + cls.spec_shaped_rewards)
        rewards += "\n\n" + textwrap.fill(shaped, PROSE_WIDTH)
    sections = (
        ("Action Space", action),
        ("Observation Space", f"``Dict``:\n\n{observations}"),
        ("Rewards", rewards),
    )
    return {
        "spaces_and_rewards": "\n\n".join(f"{title}\n{'-' * len(title)}\n{text}" for title, text in sections),
        "common_arguments": COMMON_ARGUMENTS.format(max_episode_s=cls.default_max_episode_s),
    }


def _channels(idx: str) -> int:
    """Channels of an action table row: ``"4"`` is one, ``"9-13"`` five."""
    first, _, last = idx.partition("-")
    return int(last or first) - int(first) + 1


def expand(doc: str | None, texts: dict[str, str], *, owner: str = "the class") -> str | None:
    """``doc`` with each placeholder line ``{name}`` replaced by ``texts[name]``, indented
    as the placeholder was.

    Raises
    ------
    ConfigError
        If ``doc`` has a placeholder line that ``texts`` does not know.
    """
    if doc is None:
        return None

    def replace(m: re.Match) -> str:
        name = m.group("name")
        if name not in texts:
            raise ConfigError(f"{owner}'s docstring has an unknown placeholder {{{name}}}; known: {', '.join(sorted(texts))}")
        indent = m.group("indent")
        return "\n".join(indent + line if line else "" for line in texts[name].splitlines())

    return _PLACEHOLDER.sub(replace, doc)


__all__ = ["COMMON_ARGUMENTS", "PERCEPT_ROWS", "PROPRIOCEPTION_ROWS", "ROBOT_ACTION_ROWS", "expand", "parts", "rst_table"]
