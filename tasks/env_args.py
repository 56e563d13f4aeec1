"""What a task env is given: the constructor arguments every task shares, and each step's action.

Both are checked here, with a :class:`~acoustic_sim.errors.ConfigError` that names the
argument and what was expected (the arguments once, in
:class:`tasks.base.HearingTaskEnv`'s constructor; the action at every step). The two action
modes are :data:`tasks.skills.ACTION_MODES` (``"joints"``: the layout's channels,
``"skill"``: the task family's small space, mapped to joint targets by the skill); the two
reward modes are :data:`REWARD_MODES`.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.errors import ConfigError
from tasks.auditory import PROFILES
from tasks.skills import ACTION_MODES, Skill

REWARD_MODES = ("sparse", "shaped")
"""The tasks' ``reward_mode`` values."""


def check_arguments(*, render_mode: str | None, render_modes: list[str], profile: str, action_mode: str,
                    reward_mode: str, max_episode_s: float | None, default_max_episode_s: float,
                    image_size: tuple[int, int], torch_threads: int | None) -> tuple[float, tuple[int, int]]:
    """Check the common arguments (see :class:`tasks.base.HearingTaskEnv`).

    Returns
    -------
    max_s : float or int
        The episode's time limit (s): ``max_episode_s``, or the task's default if None.
    image_size : tuple of int
        (height, width), pixels.

    Raises
    ------
    ConfigError
        For the first argument out of its range.
    """
    if render_mode is not None and render_mode not in render_modes:
        raise ConfigError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
    if profile not in PROFILES:
        raise ConfigError(f"profile must be one of {PROFILES}, got {profile!r}")
    if action_mode not in ACTION_MODES:
        raise ConfigError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")
    if reward_mode not in REWARD_MODES:
        raise ConfigError(f"reward_mode must be one of {REWARD_MODES}, got {reward_mode!r}")
    max_s = default_max_episode_s if max_episode_s is None else max_episode_s
    if not (isinstance(max_s, (int, float)) and np.isfinite(max_s) and max_s > 0):
        raise ConfigError(f"max_episode_s must be a positive number of seconds, got {max_episode_s!r}")
    h, w = image_size
    if not all(isinstance(v, int) and 16 <= v <= 480 for v in (h, w)) or w > 640:
        raise ConfigError(f"image_size must be (height, width) in pixels, 16-480 x 16-640, got {image_size!r}")
    if torch_threads is not None and (not isinstance(torch_threads, int) or torch_threads < 1):
        raise ConfigError(f"torch_threads must be None or a positive integer, got {torch_threads!r}")
    return max_s, (h, w)


def joint_action(action, n: int, action_mode: str, skill: Skill | None) -> np.ndarray:
    """A step's action as the layout's normalized channels (float64, -1..1).

    Parameters
    ----------
    action : array_like, shape (n,)
        The action, in ``action_mode``'s space (clipped to -1..1).
    n : int
        Components of the action space.
    action_mode : str
        For the error message.
    skill : tasks.skills.Skill or None
        Maps a ``skill`` mode action to the layout's channels; None in ``joints`` mode.

    Raises
    ------
    ConfigError
        If ``action`` is not ``n`` finite numbers.
    """
    a = np.asarray(action, dtype=np.float64).reshape(-1)
    if a.shape != (n,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"action must be {n} finite numbers in [-1, 1] ({action_mode} mode), got shape {a.shape}")
    a = np.clip(a, -1.0, 1.0)
    if skill is not None:
        a = skill.to_joints(a).astype(np.float64)
    return a


__all__ = ["REWARD_MODES", "check_arguments", "joint_action"]
