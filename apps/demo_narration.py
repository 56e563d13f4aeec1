"""The demo episode in words: when the alarm started, when and from where the robot heard it,
what else it heard, when the hand let go, and the outcome.

What the robot heard comes from the observations recorded in the :class:`~apps.demo_trace.Trace`
(as the policy reads them); what was really there from ``info`` (ground truth), only to tell
the reader. Nothing is smoothed over: the narration reports what happened, whatever it is.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.frames import in_lateral_region
from apps.demo_trace import LABEL, Trace, alarm_estimates, car_azimuth_deg, runs


def side_words(az: float) -> str:
    """Where an azimuth (deg, + left) is, in words: in front, front left, left, behind, ..."""
    a = (az + 180.0) % 360.0 - 180.0
    names = ["behind", "behind on the right", "on the right", "in front on the right", "in front",
             "in front on the left", "on the left", "behind on the left", "behind"]
    return names[int(np.floor((a + 180.0 + 22.5) / 45.0))]


def narrate(trace: Trace, record: dict, *, threshold: float, lateral_range_deg: tuple, success_window_s: float, seed: int,
            profile: str, elevation_deg: tuple = (-90.0, 90.0)) -> tuple[str, dict]:
    """The episode in words, in time order, and the moments it names (for ``demo.json``).

    What the robot heard comes from the observations (the reverse alarm's probability and
    estimated direction, as the policy reads them); what was really there comes from
    ``info`` (ground truth), only to tell the reader.

    Parameters
    ----------
    trace : Trace
    record : dict
        The runner's record of the episode.
    threshold : float
        Probability from which the alarm counts as heard (the scripted policy's), 0..1.
    lateral_range_deg : tuple of float
        (lowest, highest) lateral angle from the turned head (deg, + left) that the policy
        accepts as the alarm's (:class:`policies.scripted.ScriptedReverseAlarm`: the
        dashboard speaker and its front-back mirror image, which the ears cannot tell apart).
    elevation_deg : tuple of float
        (lowest, highest) elevation (deg, car frame) of that region (the policy's).
    success_window_s : float
        Longest alarm-to-release time of a success (the task's), s.
    seed : int
    profile : str

    Returns
    -------
    text : str
    moments : dict
        ``alarm_start_s``, ``recognized_s``, ``recognized_azimuth_deg``, ``accepted_s`` (first
        placed in the alarm's region),
        ``release_s`` (seconds since the episode's start, None when it did not happen) and
        ``outcome``.
    """
    from acoustic_sim.viz.episode import outcome_words

    t = np.asarray(trace.t)
    p, d, has, lat, el = alarm_estimates(trace)
    heard = (p >= threshold) & has
    neck = trace.necks()
    az = np.array([car_azimuth_deg(v, n) if h else np.nan for v, n, h in zip(d, neck, has)])
    accepted = np.array([h and in_lateral_region(v, float(n[1]), lateral_range_deg=lateral_range_deg,
                                                 elevation_deg=elevation_deg)
                         for v, n, h in zip(d, neck, has)], dtype=bool)
    (llo, lhi), (lo, hi) = lateral_range_deg, elevation_deg
    bounds = [f"lateral angle {llo:+.0f} to {lhi:+.0f} deg from the turned head"]
    if lo > -90.0:
        bounds.append(f"elevation at least {lo:+.0f} deg")
    if hi < 90.0:
        bounds.append(f"elevation at most {hi:+.0f} deg")
    region = f"the alarm's region: {', '.join(bounds)}"
    onset = record["target_onset_s"]
    onset = None if onset is None else onset - trace.start_s
    release = record.get("release_s")
    release = None if release is None else release - trace.start_s
    moments: dict = {"alarm_start_s": onset, "recognized_s": None, "recognized_azimuth_deg": None, "accepted_s": None,
                     "release_s": release, "outcome": record["outcome"]}
    timeline: list[tuple[float, int, str]] = []  # (time, order at equal times, text)

    for te, e in trace.events:
        if e["kind"] == "distractor":
            detail = f" ({e['detail']})" if e["detail"] else ""
            timeline.append((te, 1, f"distractor: {e['label'].replace('_', ' ')}{detail}"))
    # What the robot took for a reverse alarm before the real one: the distractors' test.
    for a, b in runs(heard & (t < (onset if onset is not None else np.inf))):
        where = float(np.nanmedian(az[a:b + 1]))
        timeline.append((t[a], 2, (f"heard a reverse alarm from {where:+.0f} deg ({side_words(where)}) until "
                                   f"{t[b]:.2f} s{_truth(trace, a, b)}")))
    # Where the lever stood waiting for quiet (the policy's reason, step by step).
    for a, b in trace.wait_runs():
        masked = sorted({c.replace("_", " ") for w in trace.waiting[a:b + 1] for c in (w[1] if w[0] == "masked" else ())})
        why = [f"hearing {', '.join(masked)}"] if masked else []
        if any(w[0] == "settling" for w in trace.waiting[a:b + 1]):
            why.append(f"after hearing a {LABEL.replace('_', ' ')}")
        timeline.append((t[a], 1, f"the lever waits for quiet ({'; '.join(why)}) until {t[min(b + 1, len(t) - 1)]:.2f} s"))
    tail = []
    if onset is None:
        tail.append("the car's reverse alarm never started (the lever did not reach R)")
    else:
        true_alarm = next((x["alarm"] for x in trace.true_az if "alarm" in x), None)
        where_true = f" (truly {true_alarm:+.0f} deg, {side_words(true_alarm)})" if true_alarm is not None else ""
        timeline.append((onset, 0, f"the lever enters R and the car's reverse alarm starts{where_true}"))
        after = np.flatnonzero(heard & (t >= onset))
        if after.size:
            j = int(after[0])
            a = float(az[j])
            timeline.append((t[j], 3, (f"recognized as a reverse alarm (p = {p[j]:.2f}), {t[j] - onset:.2f} s after it "
                                      f"started, from {a:+.0f} deg azimuth, {el[j]:+.0f} deg elevation "
                                      f"({side_words(a)}; lateral {lat[j]:+.0f} deg from the head, "
                                      f"{'inside' if accepted[j] else 'outside'} {region})")))
            moments.update(recognized_s=float(t[j]), recognized_azimuth_deg=a)
            inside = after[accepted[after]]
            if inside.size and inside[0] != j:
                f = int(inside[0])
                timeline.append((t[f], 4, f"first placed in the alarm's region: lateral {lat[f]:+.0f} deg "
                                          f"({az[f]:+.0f} deg azimuth, {el[f]:+.0f} deg elevation)"))
            if inside.size:
                moments["accepted_s"] = float(t[int(inside[0])])
            upto = after[t[after] <= (release if release is not None else np.inf)]
            n_front = int(np.sum(accepted[upto]))
            tail.append(f"while the alarm sounded{' and the hand held on' if release is not None else ''}, "
                        f"{upto.size} frames heard it with a direction: median {float(np.median(az[upto])):+.0f} deg, "
                        f"{n_front} of them in the alarm's region")
        else:
            best = float(np.max(p[t >= onset])) if np.any(t >= onset) else float("nan")
            tail.append(f"the alarm was never recognized with a direction (highest probability {best:.2f}, "
                        f"threshold {threshold:.2f})")
    if release is not None:
        gear = f"gear {record['gear']}" if record.get("gear") else "the lever between gears"
        rel = f", {release - onset:.2f} s after the alarm started" if onset is not None and release >= onset else (
            ", before the car's alarm started")
        timeline.append((release, 5, f"the left hand lets go of the lever ({gear}){rel}"))
    else:
        tail.append("the left hand never let go")

    verdict = outcome_words(record["outcome"])
    if record["reaction_s"] is not None:
        verdict += f" (reaction {record['reaction_s']:.2f} s; a success lets go within {success_window_s:.1f} s)"
    head = (f"acoustic-sim demo: ReverseAlarm, scripted policy, seed {seed}, {profile} models "
            f"({record['steps']} steps, {record['episode_s']:.2f} s simulated)")
    lines = [head, *(f"  {te:5.2f} s  {text}" for te, _, text in sorted(timeline, key=lambda x: (x[0], x[1])))]
    lines += [f"  {text}" for text in tail]
    lines.append(f"  outcome at {t[-1]:.2f} s: {verdict}")
    return "\n".join(lines), moments


def _truth(trace: Trace, a: int, b: int) -> str:
    """What was really beeping during steps a..b (ground truth), as a clause."""
    beepers = {}
    for x in trace.true_az[a:b + 1]:
        for src, az in x.items():
            if trace.labels.get(src) == LABEL:
                beepers.setdefault(src, []).append(az)
    if not beepers:
        return " (nothing was beeping: a false detection)"
    src, azs = max(beepers.items(), key=lambda kv: len(kv[1]))
    name = "another vehicle's beeper" if src.startswith("task/") else src
    m = float(np.median(azs))
    return f" (it was {name}, truly {m:+.0f} deg, {side_words(m)})"


__all__ = ["narrate", "side_words"]
