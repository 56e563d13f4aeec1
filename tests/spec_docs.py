"""The generator of the task envs' shared specification text, kept for the tests only.

A task's class docstring is its specification in the Gymnasium style (Description, Action
Space, Observation Space, Rewards, Starting State, Episode End, Arguments), written out in
the task's source file. The action and observation tables, the rewards and the arguments
every task shares are the same text in each; :func:`parts` writes them from the rows below
and from the tasks' own constants (the reward weights, the skills' rows, the default time
limits), and ``tests/test_tasks.py`` checks that each docstring holds them word for word, so
the written text cannot drift from the code or from the other tasks (not a test module itself).
"""

from __future__ import annotations

import textwrap

from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.errors import ConfigError
from tasks.cabin import PROGRESS_WEIGHT, TIMING_WEIGHT
from tasks.call_response import FACING_WEIGHT, TIME_WEIGHT
from tasks.skills import LeverSkill, TurnSkill

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

SCENES: dict[str, dict] = {
    "cabin": {
        "action_rows": (
            ("14", "grasp_left", "-1 .. 1", "> 0 hold, <= 0 open"),
            ("15", "grasp_right", "-1 .. 1", "> 0 hold, <= 0 open"),
        ),
        "action_notes": ("A grasp command > 0 closes an open hand on its lever if the palm is within 5 cm "
                         "of the handle; <= 0 opens it."),
        "observation_rows": (("grasp", "(2,)", "1 if the left / right hand holds its lever"),),
        "rewards": "+1 on success, -1 on failure, the time limit included (both at the episode's end), 0 otherwise.",
        "shaped_rewards": (
            f"``reward_outcome`` (the sparse reward), ``reward_progress`` (the change of {PROGRESS_WEIGHT:g} x the "
            "lever's progress toward the position the task asks for, 0 at rest, 1 there: a potential, so over an "
            f"episode it sums to at most {PROGRESS_WEIGHT:g}) and ``reward_timing`` (on success, {TIMING_WEIGHT:g} x "
            "(1 - reaction / success_window_s)). A success returns at least 1, a failure at most "
            f"{PROGRESS_WEIGHT - 1:g}."),
        "skill_rows": LeverSkill.rows,
    },
    "room": {
        "action_rows": (
            ("14", "left_wheel (+ forward)", "-5 .. 5", "rad/s"),
            ("15", "right_wheel (+ forward)", "-5 .. 5", "rad/s"),
        ),
        "action_notes": ("The wheels (0.30 m radius, 0.60 m apart) are velocity servos: equal speeds drive, "
                         "opposite speeds turn on the spot (right wheel forward turns left, 1 rad/s each way "
                         "= 57 deg/s)."),
        "observation_rows": (
            ("base", "(3,)", ("the wheelchair's odometry: heading since the start (rad, +-pi, + left), forward speed "
                              "(m/s), yaw rate (rad/s)")),
        ),
        "rewards": "+1 when the caller is looked at, 0 otherwise (``wrong_person``, ``too_late``, ``timeout``).",
        "shaped_rewards": (
            f"``reward_outcome`` (the sparse reward), ``reward_facing`` (the change of {FACING_WEIGHT:g} x "
            "(1 - the angle between the head's forward and the person / 180 deg): a potential, summing over an "
            f"episode to within +-{FACING_WEIGHT:g}) and ``reward_time`` (-{TIME_WEIGHT:g} / the episode's step limit "
            f"each step). A success returns at least {1 - FACING_WEIGHT - TIME_WEIGHT:g}, a failure at most "
            f"{FACING_WEIGHT:g}."),
        "skill_rows": TurnSkill.rows,
    },
}
"""Per scene (a task family): its action channels after the robot's joints (idx, channel,
range, unit) and what they do, its observation rows after proprioception, the Rewards
section's sparse and shaped text, and the ``skill`` action mode's rows."""

MEANING_WIDTH = 67
"""Characters of the observation table's last column before it wraps."""

PROSE_WIDTH = 92
"""Characters of a line of generated prose."""


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
    """The shared texts of a task class's docstring: ``spaces_and_rewards`` (the sections
    Action Space, Observation Space and Rewards) and ``common_arguments`` (the lines of the
    arguments every task has, at the end of Arguments)."""
    scene = SCENES[cls.scene_name]
    n = sum(_channels(idx) for idx, *_ in (*ROBOT_ACTION_ROWS, *scene["action_rows"]))
    actions = rst_table(("idx", "channel", "range", "unit"), (*ROBOT_ACTION_ROWS, *scene["action_rows"]))
    notes = ("Joint targets drive position servos (the ranges are the actuators' control ranges); "
             "``env.unwrapped.layout`` converts physical targets to actions. " + scene["action_notes"])
    observations = rst_table(("key", "shape", "meaning"), (*PROPRIOCEPTION_ROWS, *scene["observation_rows"], *PERCEPT_ROWS),
                             wrap_last=MEANING_WIDTH)
    action = (f"``action_mode=\"joints\"``: ``Box(-1, 1, ({n},), float32)``, normalized targets; -1 and +1 are the "
              "ends of the range.")
    action = f"{textwrap.fill(action, PROSE_WIDTH)}\n\n{actions}\n\n{textwrap.fill(notes, PROSE_WIDTH)}"
    skill = (f"``action_mode=\"skill\"``: ``Box(-1, 1, ({len(scene['skill_rows'])},), float32)``; the zero action keeps "
             "everything as it is (nothing moves, nothing lets go), the rest of the robot holds its rest pose "
             "(:mod:`tasks.skills`).")
    table = rst_table(("idx", "component", "range", "meaning"), scene["skill_rows"], wrap_last=MEANING_WIDTH)
    action += f"\n\n{textwrap.fill(skill, PROSE_WIDTH)}\n\n{table}"
    rewards = textwrap.fill("``reward_mode=\"sparse\"``: " + scene["rewards"], PROSE_WIDTH)
    shaped = ("``reward_mode=\"shaped\"``: the sum of the terms that ``info`` reports each step in both modes: "
              + scene["shaped_rewards"])
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


def indented(text: str, indent: str = "    ") -> str:
    """``text`` as it stands in a class docstring: each line indented, blank lines empty."""
    return "\n".join(indent + line if line else "" for line in text.splitlines())


__all__ = ["COMMON_ARGUMENTS", "PERCEPT_ROWS", "PROPRIOCEPTION_ROWS", "ROBOT_ACTION_ROWS", "SCENES", "indented", "parts",
           "rst_table"]
