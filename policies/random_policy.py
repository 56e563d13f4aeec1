"""The random baselines: uniform random actions, and random arm actions with the hands kept closed.

``random`` draws every action component uniformly from the env's normalized action space
(in the cabin, a grasp command <= 0 opens the hand, so about half the first steps let go);
``random-hold`` draws the joints (and wheels) the same way but keeps both grasp commands
closed, so an episode ends only through the lever's own mechanism or the time limit. What
they show: how often a task is met by chance, the floor under every other policy.

Each episode's draws come from a generator seeded by the episode's seed
(:meth:`RandomPolicy.reset`): the same seed gives the same actions, independent of the
episodes run before it.
"""

from __future__ import annotations

import numpy as np

from policies.task_policy import TaskPolicy


class RandomPolicy(TaskPolicy):
    """Uniform random normalized actions, from a generator seeded per episode.

    Parameters
    ----------
    env : gymnasium.Env
        The task env (its action layout).
    hold : bool
        Keep the grasp commands at +1 (the hands stay on their levers); only the cabin has them.
    """

    stream = 0x5EED
    """Mixed with the episode's seed so that the policy's draws never repeat the env's."""

    def __init__(self, env, *, hold: bool = False) -> None:
        super().__init__(env)
        self.hold = bool(hold)
        self._grasp = [i for i, n in enumerate(self.layout.names) if n.startswith("grasp_")]
        self.rng = np.random.default_rng([self.stream, 0])

    def reset(self, obs, info, seed: int | None = None) -> None:
        """Start an episode; ``seed`` (the env's episode seed) seeds this episode's draws."""
        super().reset(obs, info, seed)
        self.rng = np.random.default_rng([self.stream, 0 if seed is None else int(seed)])

    def act(self, obs, info) -> np.ndarray:
        a = self.rng.uniform(-1.0, 1.0, size=len(self.layout)).astype(np.float32)
        if self.hold:
            a[self._grasp] = 1.0
        self.steps += 1
        return a


class RandomHoldPolicy(RandomPolicy):
    """Random joint (and wheel) actions with both hands kept closed on their levers."""

    def __init__(self, env) -> None:
        super().__init__(env, hold=True)


POLICY_CLASSES = {task: RandomPolicy for task in ("reverse-alarm", "parking-brake", "call-response")}
"""Task name -> ``random`` policy class."""

HOLD_POLICY_CLASSES = {task: RandomHoldPolicy for task in ("reverse-alarm", "parking-brake", "call-response")}
"""Task name -> ``random-hold`` policy class."""

__all__ = ["HOLD_POLICY_CLASSES", "POLICY_CLASSES", "RandomHoldPolicy", "RandomPolicy"]
