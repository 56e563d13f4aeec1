"""What every policy shares: the env's action layout and a step counter, and the observation
readers (is a class heard, from where; how the head is turned).

The policies read the observation only (the oracle also reads ``info``); these helpers are
the one place that indexes it.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from tasks.base import CLASSES, CONTROL_DT


class TaskPolicy:
    """Base of the policies: the env's static action layout, a step counter.

    Parameters
    ----------
    env : gymnasium.Env
        A task env (wrapped or not); only its static ``layout`` and ``task`` are read.
    """

    def __init__(self, env) -> None:
        self.env = env.unwrapped
        self.layout = self.env.layout
        self.steps = 0

    def reset(self, obs, info, seed: int | None = None) -> None:
        """Start of an episode: the observation and info of ``env.reset`` and, when the caller
        knows it, the episode's seed (a policy that draws random numbers seeds them from it)."""
        self.steps = 0

    def act(self, obs, info) -> np.ndarray:
        """The action (normalized, float32) for the observation (and, for the oracle, info)."""
        raise NotImplementedError

    @property
    def time_s(self) -> float:
        """Seconds since the episode's start, at the step about to be taken."""
        return self.steps * CONTROL_DT


class Votes:
    """Frame votes over a sliding window: for (the class from the accepted region) or against.

    The policy acts when at least ``votes`` of the last ``window`` frames voted for and more
    voted for than against: one stray frame (a mislocalized distractor, a front-back flip)
    does not decide.
    """

    def __init__(self, window: int, votes: int) -> None:
        self.window, self.votes = int(window), int(votes)
        self.frames: deque = deque(maxlen=self.window)

    def reset(self) -> None:
        self.frames.clear()

    def push(self, pro: bool, con: bool) -> bool:
        """Add one frame's vote; True when the evidence decides."""
        self.frames.append((bool(pro), bool(con)))
        pros = sum(p for p, _ in self.frames)
        cons = sum(c for _, c in self.frames)
        return pros >= self.votes and pros > cons


def heard(obs, label: str, threshold: float, min_conf: float) -> tuple[bool, np.ndarray | None]:
    """Whether ``label`` is heard in this frame, and its direction when it has a confident estimate."""
    i = CLASSES.index(label)
    on = float(obs["class_prob"][i]) >= threshold
    d = class_direction(obs, i)
    has = float(obs["class_conf"][i]) > min_conf and float(np.linalg.norm(d)) > 0.5
    return on, (d if on and has else None)


def class_direction(obs, i: int) -> np.ndarray:
    """Class ``i``'s estimated direction (head frame, (3,)) from the flat ``class_dir``."""
    return np.asarray(obs["class_dir"][3 * i : 3 * i + 3], float)


def head_pose(obs) -> tuple[float, float, float]:
    """The head's turn on the frame fixed at the episode's start, from the observation: the
    neck's yaw and pitch (rad, proprioception) and the wheelchair's odometry heading (rad; 0
    without a wheelchair, no ``base`` in the observation: the car seat), so that
    ``v = Rz(heading) Rz(neck_yaw) Ry(neck_pitch) v_head``."""
    heading = float(obs["base"][0]) if "base" in obs else 0.0
    return float(obs["joint_pos"][0]), float(obs["joint_pos"][1]), heading


__all__ = ["TaskPolicy", "Votes", "class_direction", "head_pose", "heard"]
