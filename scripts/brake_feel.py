"""Does the arm on the parking brake feel the ratchet? Pulls with DeafParkingBrake (45 deg, no
distractors, fast models, seeds 100-105) and compares DetentFeel's feels with the clicks
(docs/notes/deaf_baseline.md, "ParkingBrake: the hand feels every pin").

    .venv/bin/python scripts/brake_feel.py
"""
import numpy as np
from tasks.parking_brake import ParkingBrakeEnv
from policies.deaf import DeafParkingBrake
from policies.lever_policy import DetentFeel
from tasks.base import CONTROL_DT
env = ParkingBrakeEnv(profile="fast", distractors=False, max_episode_s=6.0)
for rate in (8.0, 16.0):
  hits=[]; falses=[]; clicks_all=0
  for seed in range(100,106):
    obs, info = env.reset(seed=seed)
    pol = DeafParkingBrake(env, target_deg=45.0, rate_deg_s=rate, wait_s=10.0); pol.reset(obs, info, seed)
    feel = DetentFeel("right"); feel.reset(obs)
    clicks=[]; felt=[]
    for k in range(int(5.5/CONTROL_DT)):
        a = pol.act(obs, info)
        obs, r, te, tr, info = env.step(a)
        for e in info["events"]:
            if e["kind"]=="ratchet_click": clicks.append(info["step"])
        if feel.push(obs, pol.moved): felt.append(info["step"])
        if te or tr: break
    clicks_all += len(clicks)
    # a click is felt if a feel within +-3 steps
    for c in clicks: hits.append(any(abs(f-c)<=3 for f in felt))
    falses.append(sum(1 for f in felt if not any(abs(f-c)<=3 for c in clicks)))
    print(rate, seed, "clicks", clicks, "felt", felt)
  print("rate", rate, "clicks", clicks_all, "felt share", np.mean(hits), "false feels", sum(falses))
