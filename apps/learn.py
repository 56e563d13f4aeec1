"""``acoustic-sim train policy``: a policy learned from the env alone, with stable-baselines3.

PPO (``MultiInputPolicy``) on a hearing task in the skill action mode with the shaped reward
by default (:mod:`tasks.skills`: exploration there does not end an episode at once), the
``fast`` auditory models, ``--envs K`` envs (subprocesses for K > 1, one torch thread each).
Writes to ``OUT``:

- ``policy.zip`` (stable-baselines3's) and ``policy.json``: task, modes, auditory profile and
  its checkpoints (file names and sha256), observation layout, seeds, steps, code version;
- ``progress.csv``: stable-baselines3's per-update metrics plus ``rollout/success_rate``
  (TensorBoard logs too when ``tensorboard`` is installed);
- ``episodes.csv``: every training episode (env steps at its end, return, length, success);
- ``learning_curve.png``: success rate and return against env steps.

Training episodes draw their worlds from seeds ``SEED`` + env index and then from each env's
own generator: none is a held-out evaluation seed's episode.
"""

from __future__ import annotations

import csv
import hashlib
import json
import subprocess
import time
from pathlib import Path

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import check_writable_folder, write_text
from policies.learned import META, ZIP, observation_layout

ALGOS = ("ppo",)
"""Algorithms of ``--algo``."""

PPO_ARGS = {"n_steps": 256, "batch_size": 128, "n_epochs": 10, "gamma": 0.99, "learning_rate": 3e-4}
"""stable-baselines3 PPO arguments (per env ``n_steps``); the library's defaults otherwise."""

SUCCESS_WINDOW = 50
"""Episodes in the running success rate."""


def _make_env(task: str, profile: str, action_mode: str, reward_mode: str):
    """A picklable env factory for stable-baselines3's vector envs (one torch thread)."""

    def make():
        import gymnasium as gym
        import torch

        import acoustic_sim  # noqa: F401  (registers the ids)
        from acoustic_sim.registration import TASK_IDS

        torch.set_num_threads(1)
        return gym.make(TASK_IDS[task][0], profile=profile, action_mode=action_mode, reward_mode=reward_mode)

    return make


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def auditory_checkpoints(profile: str, hrtf: str = "kemar") -> dict:
    """The cached auditory models a task env of ``profile`` loads: file names and sha256 (16 hex)."""
    from acoustic_sim.auditory.melcnn import MelCNN
    from acoustic_sim.auditory.ssdenet import SSDENetBank
    from tasks.auditory import load_models

    ears, grid, _bank, _cnn = load_models(hrtf, profile)  # trains them first if the cache lacks them
    out = {}
    for kind, path in (("ssdenet", SSDENetBank.cache_path(ears, grid, profile)), ("melcnn", MelCNN.cache_path(profile))):
        out[kind] = {"file": path.name, "sha256": _sha256(path) if path.is_file() else None}
    return out


def code_version() -> str:
    """``git describe`` of the checkout (with ``-dirty``), or the package version."""
    try:
        return subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True, text=True, timeout=10,
                              cwd=Path(__file__).resolve().parent, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        from importlib.metadata import version

        return version("acoustic-sim")


def train_policy(task: str, *, out, algo: str = "ppo", steps: int = 100_000, envs: int = 1, seed: int = 0,
                 profile: str = "fast", action_mode: str = "skill", reward_mode: str = "shaped",
                 progress: bool = True, ppo_args: dict | None = None, return_model: bool = False):
    """Train a policy and write it with its metadata, metrics and learning curve to ``out``.

    Parameters
    ----------
    task : str
        ``reverse-alarm``, ``parking-brake`` or ``call-response``.
    out : str or pathlib.Path
        Output folder (created; checked before the training starts).
    algo : str
        ``ppo``.
    steps : int
        Env steps to train (all envs together).
    envs : int
        Envs stepped together (subprocesses when more than one).
    seed : int
        Seed of the network's initialization, the sampling and the envs' first worlds.
    profile, action_mode, reward_mode : str
        The env's auditory models and modes.
    ppo_args : dict, optional
        Overrides of :data:`PPO_ARGS`.

    return_model : bool
        Also return the trained model (tests: the saved policy must act as it does).

    Returns
    -------
    dict
        The metadata written to ``policy.json`` (and the model, with ``return_model``).

    Raises
    ------
    ConfigError
        For an unknown task or algorithm, non-positive steps or envs, a negative seed, or an
        unwritable ``out``.
    """
    from acoustic_sim.registration import TASK_IDS

    if task not in TASK_IDS:
        raise ConfigError(f"unknown task {task!r}; valid: {', '.join(TASK_IDS)}")
    if algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {algo!r}; valid: {', '.join(ALGOS)}")
    for name, value, low in (("steps", steps, 1), ("envs", envs, 1), ("seed", seed, 0)):
        if not isinstance(value, int) or value < low:
            raise ConfigError(f"--{name} must be an integer >= {low}, got {value!r}")
    out = check_writable_folder(out, what="--out")
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    checkpoints = auditory_checkpoints(profile)  # trained here, once, not in every worker
    torch.set_num_threads(1)
    factory = _make_env(task, profile, action_mode, reward_mode)
    venv = make_vec_env(factory, n_envs=envs, seed=seed, vec_env_cls=SubprocVecEnv if envs > 1 else DummyVecEnv,
                        monitor_kwargs={"info_keywords": ("success",)})
    try:
        layout = observation_layout(venv.observation_space)
        args = {**PPO_ARGS, **(ppo_args or {})}
        model = PPO("MultiInputPolicy", venv, seed=seed, device="cpu", verbose=0, **args)
        formats = ["csv"]
        try:
            import tensorboard  # noqa: F401

            formats.append("tensorboard")
        except ImportError:
            pass
        model.set_logger(configure(str(out), formats))
        callback = _progress_callback(steps, progress)
        t0 = time.perf_counter()
        try:
            model.learn(total_timesteps=steps, callback=callback)
        finally:
            callback.close()
        wall = time.perf_counter() - t0
        model.save(out / ZIP)
    finally:
        venv.close()
    episodes = callback.episodes
    _write_episodes(out / "episodes.csv", episodes)
    recent = episodes[-SUCCESS_WINDOW:]
    meta = {
        "task": task, "algo": algo, "action_mode": action_mode, "reward_mode": reward_mode, "profile": profile,
        "hrtf": "kemar", "auditory_checkpoints": checkpoints, "observation": layout,
        "action_shape": list(venv.action_space.shape), "seed": seed, "envs": envs, "steps": int(model.num_timesteps),
        "algo_args": args, "episodes": len(episodes),
        "final_success_rate": round(sum(e[3] for e in recent) / len(recent), 4) if recent else None,
        "wall_s": round(wall, 1), "env_steps_per_s": round(model.num_timesteps / wall, 1),
        "code_version": code_version(), "stable_baselines3": __import__("stable_baselines3").__version__,
    }
    write_text(out / META, json.dumps(meta, indent=1) + "\n")
    learning_curve(out / "episodes.csv", out / "learning_curve.png", title=f"{task}: {algo} ({action_mode}, {reward_mode})")
    return (meta, model) if return_model else meta


def _progress_callback(total: int, progress: bool):
    """A stable-baselines3 callback: a progress bar with the running success rate, the episodes'
    records, and ``rollout/success_rate`` in the per-update metrics (defined here: the library
    loads only when a training runs)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from acoustic_sim.progress import progress_bar

    class Callback(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.episodes: list[tuple[int, float, int, bool]] = []
            self.bar = progress_bar(total=total, desc="train policy", disable=not progress, dynamic_ncols=True)

        def _rate(self) -> float | None:
            recent = self.episodes[-SUCCESS_WINDOW:]
            return sum(e[3] for e in recent) / len(recent) if recent else None

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                ep = info.get("episode")
                if ep is not None:
                    self.episodes.append((int(self.num_timesteps), float(ep["r"]), int(ep["l"]), bool(info.get("success"))))
            self.bar.update(self.training_env.num_envs)
            rate = self._rate()
            if rate is not None and self.n_calls % 16 == 0:
                self.bar.set_postfix(success=f"{rate:.2f}", episodes=len(self.episodes))
            return True

        def _on_rollout_end(self) -> None:
            rate = self._rate()
            if rate is not None:
                self.logger.record("rollout/success_rate", rate)

        def close(self) -> None:
            self.bar.close()

    return Callback()


def _write_episodes(path: Path, episodes) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["env_steps", "return", "length", "success"])
        w.writerows([(s, round(r, 6), n, int(ok)) for s, r, n, ok in episodes])


def learning_curve(episodes_csv, png, *, title: str = "") -> Path:
    """Success rate and return (running means over :data:`SUCCESS_WINDOW` episodes) against
    env steps, from ``episodes.csv``."""
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = list(csv.DictReader(open(episodes_csv)))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    if rows:
        x = np.array([float(r["env_steps"]) for r in rows])
        for ax, key, label in ((axes[0], "success", "success rate"), (axes[1], "return", "return")):
            y = np.array([float(r[key]) for r in rows])
            k = min(SUCCESS_WINDOW, len(y))
            mean = np.convolve(y, np.ones(k) / k, mode="valid")
            ax.plot(x, y, ".", ms=2, alpha=0.3, color="0.5")
            ax.plot(x[k - 1:], mean, color="C0", label=f"running mean of {k} episodes")
            ax.set_xlabel("env steps")
            ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v / 1000:g}k"))
            ax.set_ylabel(label)
            ax.legend(loc="upper left", fontsize=8)
        axes[0].set_ylim(-0.05, 1.05)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return Path(png)


def add_parser(train_parser) -> None:
    """The ``train policy`` options, added to the ``train`` command's parser."""
    g = train_parser.add_argument_group("policy only (train policy)")
    g.add_argument("--task", choices=("reverse-alarm", "parking-brake", "call-response"), help="the task to learn")
    g.add_argument("--algo", choices=ALGOS, default="ppo", help="learning algorithm (default ppo, stable-baselines3)")
    g.add_argument("--steps", type=int, default=100_000, help="env steps to train, all envs together (default 100000)")
    g.add_argument("--envs", type=int, default=1, help="envs stepped together, in subprocesses when more than one (default 1)")
    g.add_argument("--action-mode", choices=("joints", "skill"), default="skill", help="the env's action mode (default skill)")
    g.add_argument("--reward-mode", choices=("sparse", "shaped"), default="shaped", help="the env's reward (default shaped)")


def cmd_train_policy(args) -> int:
    if args.task is None:
        raise ConfigError("train policy needs --task")
    if args.out is None:
        raise ConfigError("train policy needs --out (the folder for policy.zip, policy.json and the curves)")
    if args.hrtf != "kemar":
        raise ConfigError("--hrtf applies to ssdenet only (the task envs hear with KEMAR's ears)")
    meta = train_policy(args.task, out=args.out, algo=args.algo, steps=args.steps, envs=args.envs,
                        seed=0 if args.seed is None else args.seed, profile=args.profile or "fast",
                        action_mode=args.action_mode, reward_mode=args.reward_mode)
    print(json.dumps({k: meta[k] for k in ("task", "steps", "episodes", "final_success_rate", "wall_s", "env_steps_per_s")}))
    print(f"wrote {Path(args.out) / ZIP}, {META}, progress.csv, episodes.csv, learning_curve.png")
    return 0


__all__ = ["ALGOS", "PPO_ARGS", "add_parser", "auditory_checkpoints", "cmd_train_policy", "learning_curve", "train_policy"]
