"""How long a turn the right way and the wrong way take to look at the caller, acting on the
step after the call starts (the oracle: perfect hearing, no delay): the measurement behind
tasks.call_response.RESPONSE_WINDOW_S (docs/notes/call_response.md).

    .venv/bin/python scripts/turn_speeds.py [--episodes 40] [--seed 3000]

The wrong way: the wheelchair turns the long way round at the same wheel speed until the
caller is within the short way's reach, then the gaze is the oracle's. Prints, per episode,
the caller's bearing and both times (s from the call's start to the end of the look), and
the share of wrong-way turns within the window; ``--react-s`` delays both by a listener's
decision time.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from policies.oracle import OracleCallResponse
from policies.turn_policy import wrap_rad
from tasks.call_response import RESPONSE_WINDOW_S, CallResponseEnv


class DelayedOracle(OracleCallResponse):
    """The oracle, acting ``react_s`` after the call starts (a listener's decision time)."""

    react_s = 0.0

    def act(self, obs, info):
        onset = info.get("target_onset_s")
        if onset is None or self.env.unwrapped.time_s - onset < self.react_s - 1e-9:
            self.steps += 1
            return self.gaze_action(obs)
        return super().act(obs, info)


class WrongWayOracle(DelayedOracle):
    """The oracle's gaze, but the wheelchair first turns the long way round."""

    def reset(self, obs, info, seed=None):
        super().reset(obs, info, seed)
        self.long_way: float | None = None  # +1 / -1 while turning the long way

    def act(self, obs, info):
        action = super().act(obs, info)
        if self.target is None:
            return action
        rel = wrap_rad(self.target - float(obs["base"][0]))
        if self.long_way is None:
            self.long_way = -1.0 if rel > 0 else 1.0
        if self.long_way != 0.0:
            # Until the target is within the reach on the far side, drive the chair the other way.
            if self.long_way * rel > 0 and abs(rel) < math.radians(self.stop_body_deg):
                self.long_way = 0.0
            else:
                w = self.wheel_speed * self.long_way
                return self.layout.action({"left_wheel": -w, "right_wheel": w,
                                           "neck_yaw": self.long_way * math.radians(self.neck_max_deg),
                                           "eye_yaw": self.long_way * math.radians(self.eye_max_deg)})
        return action


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--episodes", type=int, default=40)
    p.add_argument("--seed", type=int, default=3000)
    p.add_argument("--react-s", type=float, default=0.0, help="the oracle acts this long after the call starts (s)")
    args = p.parse_args()
    DelayedOracle.react_s = args.react_s
    env = CallResponseEnv(profile="fast", response_window_s=None, people=(1, 1), distractors=False)
    rows = []
    for seed in range(args.seed, args.seed + args.episodes):
        times = []
        for cls in (DelayedOracle, WrongWayOracle):
            policy = cls(env)
            obs, info = env.reset(seed=seed)
            bearing = info["person_bearing_deg"]
            policy.reset(obs, info, seed)
            done = False
            while not done:
                obs, _, terminated, truncated, info = env.step(policy.act(obs, info))
                done = terminated or truncated
            times.append(info["reaction_s"] if info["success"] else float("inf"))
        rows.append((bearing, *times))
        print(f"seed {seed}  bearing {bearing:7.1f} deg  right way {times[0]:5.2f} s  wrong way {times[1]:5.2f} s")
    r = np.array(rows)
    print(f"right way: max {r[:, 1].max():.2f} s, median {np.median(r[:, 1]):.2f} s")
    print(f"wrong way: min {r[:, 2].min():.2f} s, median {np.median(r[:, 2]):.2f} s")
    for w in (1.0, 1.25, RESPONSE_WINDOW_S, 2.0):
        print(f"window {w:.2f} s: right way within {np.mean(r[:, 1] <= w):.2f}, wrong way within {np.mean(r[:, 2] <= w):.2f}")


if __name__ == "__main__":
    main()
