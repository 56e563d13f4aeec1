"""How well the ears place the caller's voice from a still head: per episode, the median
azimuth error of the estimate and of the better of it and its front-back mirror image, and
the share of frames in which the mirror image is nearer the truth (docs/notes/call_response.md).

    .venv/bin/python scripts/voice_estimates.py [--profile fast] [--episodes 20] [--seed 3000]

The robot does not move (the zero action); frames from the call's start to 0.6 s after it.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from policies.task_policy import heard
from tasks.call_response import CallResponseEnv


def _err(a: float, b: float) -> float:
    return abs(math.degrees((a - b + math.pi) % (2 * math.pi) - math.pi))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--profile", choices=("fast", "paper"), default="fast")
    p.add_argument("--episodes", type=int, default=20)
    p.add_argument("--seed", type=int, default=3000)
    args = p.parse_args()
    env = CallResponseEnv(profile=args.profile, distractors=False)
    best_all, flipped_all = [], []
    for seed in range(args.seed, args.seed + args.episodes):
        env.reset(seed=seed)
        still = env.layout.action({})
        errs = []
        while True:
            obs, _, terminated, truncated, info = env.step(still)
            onset = info["target_onset_s"]
            if onset is not None:
                on, d = heard(obs, "human_voice", 0.5, 0.0)
                if on and d is not None:
                    t = info["person_direction"]
                    truth = math.atan2(t[1], t[0])
                    errs.append((_err(math.atan2(d[1], d[0]), truth), _err(math.atan2(d[1], -d[0]), truth)))
            if terminated or truncated or (onset is not None and env.time_s - onset > 0.6):
                break
        t = info["person_direction"]
        bearing = math.degrees(math.atan2(t[1], t[0]))
        if not errs:
            print(f"seed {seed}  caller at {bearing:6.0f} deg (head frame)  no frame with the voice")
            continue
        e = np.array(errs)
        best, flipped = float(np.median(e.min(axis=1))), float(np.mean(e[:, 1] < e[:, 0]))
        best_all.append(best)
        flipped_all.append(flipped)
        print(f"seed {seed}  caller at {bearing:6.0f} deg  frames {len(e):3d}  median error {np.median(e[:, 0]):5.1f} deg  "
              f"better of the pair {best:5.1f} deg  mirror nearer in {flipped:.2f} of the frames")
    print(f"over the episodes with frames: median better-of-pair error {np.median(best_all):.1f} deg, "
          f"mean share of frames with the mirror nearer {np.mean(flipped_all):.2f}")


if __name__ == "__main__":
    main()
