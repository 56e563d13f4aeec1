"""Throughput of stable-baselines3 PPO on ReverseAlarm in skill mode (2048 steps, one env, one
torch thread, fast models): docs/notes/learner_interface.md.

    .venv/bin/python scripts/ppo_smoke.py
"""
import time, numpy as np, torch
torch.set_num_threads(1)
import gymnasium as gym, acoustic_sim
from stable_baselines3 import PPO
from stable_baselines3.common.monitor import Monitor
env = Monitor(gym.make("acoustic_sim/ReverseAlarm-v0", profile="fast", action_mode="skill", reward_mode="shaped"))
model = PPO("MultiInputPolicy", env, n_steps=512, batch_size=128, seed=0, verbose=0)
t = time.time(); model.learn(2048); dt = time.time() - t
lens = env.get_episode_lengths(); rets = env.get_episode_rewards()
print(f"{2048/dt:.0f} steps/s, {len(lens)} episodes, median length {np.median(lens)}, outcomes via returns > 0: {np.mean(np.array(rets) > 0):.2f}")
