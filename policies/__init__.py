"""Behaviours for the hearing tasks (issue 5): ``scripted``, ``oracle`` and ``blind``.

``scripted`` is the paper's behaviour and uses only the observation; ``oracle`` reads the
ground truth in ``info`` (the upper bound of the behaviour); ``blind`` hears classes but
ignores directions (what hearing the direction is worth is scripted minus blind).

>>> env = gymnasium.make("acoustic_sim/ReverseAlarm-v0", profile="fast")
>>> policy = make_policy("scripted", env)
>>> obs, info = env.reset(seed=0); policy.reset(obs, info)
>>> obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
"""

from __future__ import annotations

from acoustic_sim.errors import ConfigError

POLICIES = ("scripted", "oracle", "blind")
"""Policy names accepted by :func:`make_policy`."""


def make_policy(name: str, env):
    """The policy ``name`` for the task of ``env`` (a task env, wrapped or not).

    Raises
    ------
    ConfigError
        For an unknown policy name or an env that is not one of the hearing tasks.
    """
    if name not in POLICIES:
        raise ConfigError(f"unknown policy {name!r}; valid: {', '.join(POLICIES)}")
    from policies import blind, oracle, scripted

    module = {"scripted": scripted, "oracle": oracle, "blind": blind}[name]
    task = getattr(env.unwrapped, "task", None)
    classes = module.POLICY_CLASSES
    if task not in classes:
        raise ConfigError(f"{type(env.unwrapped).__name__} is not a hearing task (tasks: {', '.join(classes)})")
    return classes[task](env)


__all__ = ["POLICIES", "make_policy"]
