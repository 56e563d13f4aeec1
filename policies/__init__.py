"""Behaviours for the hearing tasks: ``scripted``, ``oracle``, ``blind``, ``deaf``, ``random``, ``random-hold``.

``scripted`` is the paper's behaviour and uses only the observation; ``oracle`` reads the
ground truth in ``info`` (the upper bound of the behaviour); ``blind`` hears classes but
ignores directions (what hearing the direction is worth is scripted minus blind); ``deaf``
never reads the percept (what hearing as a whole is worth is scripted minus deaf);
``random`` and ``random-hold`` act at random (the second with the hands kept closed).

A policy is an object built from the env, ``Policy(env)``, with ``reset(obs, info, seed)``
at the start of an episode and ``act(obs, info) -> action`` at every step (``info`` is for
the oracle; the others read the observation only). Any such class plugs into ``run`` and
``eval tasks`` as ``--policy module:Class``; a policy trained by ``acoustic-sim train policy``
as ``--policy learned:PATH`` (:mod:`policies.learned`).

>>> env = gymnasium.make("acoustic_sim/ReverseAlarm-v0", profile="fast")
>>> policy = make_policy("scripted", env)
>>> obs, info = env.reset(seed=0); policy.reset(obs, info, 0)
>>> obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
"""

from __future__ import annotations

import importlib

from acoustic_sim.errors import ConfigError

POLICIES = ("scripted", "oracle", "blind", "deaf", "random", "random-hold")
"""Policy names accepted by :func:`make_policy` (besides ``module:Class``)."""

_MODULES = {"scripted": ("scripted", "POLICY_CLASSES"), "oracle": ("oracle", "POLICY_CLASSES"),
            "blind": ("blind", "POLICY_CLASSES"), "deaf": ("deaf", "POLICY_CLASSES"),
            "random": ("random_policy", "POLICY_CLASSES"), "random-hold": ("random_policy", "HOLD_POLICY_CLASSES")}


def policy_class(name: str, task: str):
    """The policy class of ``name`` (one of :data:`POLICIES`, ``module:Class`` or ``learned:PATH``,
    then a factory taking the env) for ``task``.

    Raises
    ------
    ConfigError
        For an unknown name, a ``module:Class`` that cannot be imported or is not a class
        with ``reset`` and ``act``, a learned policy of another task or with missing files,
        or a task the named policy has no class for.
    """
    from policies.learned import PREFIX

    if name.startswith(PREFIX):
        import functools

        from policies.learned import LearnedPolicy, load_metadata

        path = name[len(PREFIX):]
        meta = load_metadata(path)  # missing or unreadable files fail here
        if meta["task"] != task:
            raise ConfigError(f"learned policy {path!r} was trained for {meta['task']}, not {task}")
        return functools.partial(LearnedPolicy, path=path)
    if ":" in name:
        module_name, _, cls_name = name.partition(":")
        try:
            obj = getattr(importlib.import_module(module_name), cls_name)
        except (ImportError, AttributeError, ValueError) as e:
            raise ConfigError(f"cannot load policy {name!r}: {e}") from None
        if not (isinstance(obj, type) and callable(getattr(obj, "reset", None)) and callable(getattr(obj, "act", None))):
            raise ConfigError(f"policy {name!r} must be a class with reset(obs, info, seed) and act(obs, info)")
        return obj
    if name not in _MODULES:
        raise ConfigError(f"unknown policy {name!r}; valid: {', '.join(POLICIES)} or module:Class")
    module_name, table = _MODULES[name]
    classes = getattr(importlib.import_module(f"policies.{module_name}"), table)
    if task not in classes:
        raise ConfigError(f"no {name} policy for task {task!r} (tasks: {', '.join(classes)})")
    return classes[task]


def make_policy(name: str, env, **kwargs):
    """The policy ``name`` (one of :data:`POLICIES`, or ``module:Class``) for the task of
    ``env`` (a task env, wrapped or not); ``kwargs`` go to the class (e.g. the deaf
    policy's open-loop parameters).

    Raises
    ------
    ConfigError
        As :func:`policy_class`, or for an env that is not one of the hearing tasks.
    """
    task = getattr(env.unwrapped, "task", None)
    if task not in ("reverse-alarm", "parking-brake", "call-response") and ":" not in name:
        raise ConfigError(f"{type(env.unwrapped).__name__} is not a hearing task")
    return policy_class(name, task)(env, **kwargs)


__all__ = ["POLICIES", "make_policy", "policy_class"]
