"""A policy trained by ``acoustic-sim train policy`` (:mod:`apps.learn`), run as ``learned:PATH``.

``PATH`` is the training's output folder (or its ``policy.zip``). Beside the zip lies
``policy.json``, the metadata: the task, the action and reward modes, the auditory profile
and its checkpoints, the observation layout. A policy is refused, with the reason, in an env
of another task or action mode, or whose observation lacks a key of the training's or gives it
another shape: its network would read the wrong numbers.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from acoustic_sim.errors import ConfigError

PREFIX = "learned:"
"""Policy names ``learned:PATH`` load a trained policy."""

ZIP, META = "policy.zip", "policy.json"
"""The files of a trained policy: stable-baselines3's zip and the metadata."""


def policy_files(path) -> tuple[Path, Path]:
    """The zip and metadata of a trained policy, from its folder or its zip.

    Raises
    ------
    ConfigError
        If either file is missing.
    """
    p = Path(path)
    folder = p.parent if p.suffix == ".zip" else p
    zip_path, meta_path = folder / ZIP, folder / META
    for f in (zip_path, meta_path):
        if not f.is_file():
            raise ConfigError(f"learned policy {str(path)!r}: {f} does not exist (train one with `acoustic-sim train policy`)")
    return zip_path, meta_path


def load_metadata(path) -> dict:
    """The metadata (``policy.json``) of a trained policy; ConfigError if unreadable."""
    _, meta_path = policy_files(path)
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, ValueError) as e:
        raise ConfigError(f"learned policy {str(path)!r}: cannot read {meta_path}: {e}") from None
    for key in ("task", "action_mode", "reward_mode", "observation", "algo"):
        if key not in meta:
            raise ConfigError(f"learned policy {str(path)!r}: {meta_path} lacks {key!r}")
    return meta


def observation_layout(space) -> dict[str, list[int]]:
    """The observation's keys and shapes (what the network was built for)."""
    return {k: list(s.shape) for k, s in space.spaces.items()}


def env_kwargs(path) -> dict:
    """The env arguments a trained policy needs: its action and reward modes."""
    meta = load_metadata(path)
    return {"action_mode": meta["action_mode"], "reward_mode": meta["reward_mode"]}


class LearnedPolicy:
    """A stable-baselines3 policy acting deterministically (the mean action) from the observation.

    Parameters
    ----------
    env : gymnasium.Env
        The task env, wrapped or not; its task and action mode must be the training's, and its
        observation must hold the training's keys with their shapes (keys added since, such as
        the tracker's, are left out of the network's input).
    path : str or pathlib.Path
        The training's output folder or its ``policy.zip``.

    Raises
    ------
    ConfigError
        For missing files, or an env the policy was not trained for (the reason named).
    """

    def __init__(self, env, path) -> None:
        self.meta = load_metadata(path)
        zip_path, _ = policy_files(path)
        u = env.unwrapped
        m = self.meta
        if getattr(u, "task", None) != m["task"]:
            raise ConfigError(f"learned policy {str(path)!r} was trained for {m['task']}, not {getattr(u, 'task', None)}")
        if u.action_mode != m["action_mode"]:
            raise ConfigError(f"learned policy {str(path)!r} acts in the {m['action_mode']} action mode; this env is in "
                              f"{u.action_mode} (make it with action_mode={m['action_mode']!r})")
        layout = observation_layout(u.observation_space)
        trained = {k: list(v) for k, v in m["observation"].items()}
        if any(layout.get(k) != v for k, v in trained.items()):
            raise ConfigError(f"learned policy {str(path)!r} was trained on observations {m['observation']}, this env gives "
                              f"{layout}")
        # Keys the env gained since the training (e.g. the tracker's) are not the network's input.
        self.keys = tuple(trained)
        if m["algo"] != "ppo":
            raise ConfigError(f"learned policy {str(path)!r}: unknown algorithm {m['algo']!r}")
        from stable_baselines3 import PPO

        self.model = PPO.load(zip_path, device="cpu")

    def reset(self, obs, info, seed: int | None = None) -> None:
        """Nothing to reset: the network has no memory."""

    def act(self, obs, info) -> np.ndarray:
        action, _ = self.model.predict({k: obs[k] for k in self.keys}, deterministic=True)
        return np.asarray(action, np.float32)


__all__ = ["PREFIX", "LearnedPolicy", "env_kwargs", "load_metadata", "observation_layout", "policy_files"]
