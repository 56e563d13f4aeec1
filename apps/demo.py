"""What ``make demo`` runs: one ReverseAlarm episode with the scripted policy, told in words.

The robot sits in the car cabin with its left hand on the gearshift
(``acoustic_sim/ReverseAlarm-v0``, :mod:`tasks.reverse_alarm`), in the paper's car
(``PAPER_CAR``: R at 15 deg, the alarm as R engages). The scripted policy
(:mod:`policies.scripted`) pushes the lever toward R; entering R starts the reverse alarm in
front of the head; the policy lets go once the alarm is heard *from the front*, while
distractors (another vehicle's beeper behind or beside, a horn, the radio) try to fool it.
The episode runs through the episode runner (:func:`apps.runner.run_episode`), whose
step hook feeds both the rerun recording and the trace (:mod:`apps.demo_trace`), which the
narration (:mod:`apps.demo_narration`) and the figure (:mod:`apps.demo_figure`) read.

:func:`run_demo` writes, in ``OUT``:

``demo.png``
    Left and right mel spectrograms, the class probabilities (shaded where the lever waited
    for quiet), and the estimated lateral angle of the reverse alarm from the turned head
    over time (the angle the policy's rule reads, its accepted band shaded) with the true
    ones of the alarm and of any beeping distractor, events marked as vertical lines (as the
    paper's task figures).
``demo.rrd``
    The rerun recording of the episode (``acoustic-sim play OUT/demo.rrd``).
``demo.wav``
    What the ears heard (after the microphone model): 2-channel float32, 44.1 kHz, full
    scale 1.0 = 132 dB SPL.
``demo.json``
    The episode's record (as in ``episodes.json``) and the narrated moments.

and returns the narration: when the alarm started, when the robot recognized it and from
which direction (read from the percepts in the observations, as the policy sees them), what
else it heard, when the hand let go, and the outcome (success, or the failure and why).
Nothing is smoothed over: the narration reports what happened in the episode, whatever it is.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import check_writable_folder, write_text, write_wav
from acoustic_sim.frames import SAMPLE_RATE
from apps.demo_figure import figure
from apps.demo_narration import narrate, side_words
from apps.demo_trace import LABEL, Trace

TASK = "reverse-alarm"
PROFILES = ("fast", "paper")


def run_demo(*, out, seed: int = 0, profile: str = "fast", progress: bool = True) -> str:
    """Run the demo episode and write ``OUT/demo.{png,rrd,wav,json}``; return the narration.

    Parameters
    ----------
    out : str or pathlib.Path
        Output folder (created).
    seed : int
        Episode seed, >= 0: same seed, same episode.
    profile : str
        Auditory models: ``fast`` (small; trained in about three minutes on a CPU the first time,
        then cached) or ``paper`` (the paper's networks; several minutes to train the first time).
    progress : bool
        Show the models' training progress bars (the episode itself takes seconds).

    Returns
    -------
    str
        The narration (also in ``demo.json``), ending with the files written.

    Raises
    ------
    ConfigError
        For a bad seed or profile.
    RecordingError
        If ``OUT/demo.rrd`` cannot be written.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    if profile not in PROFILES:
        raise ConfigError(f"profile must be one of {', '.join(PROFILES)}, got {profile!r}")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"output folder {str(out)!r} is a file")
    check_writable_folder(out, what="--out")  # before the models train, not after
    from apps.runner import make_env, run_episode
    from acoustic_sim.viz.episode import EpisodeRecorder

    recorder = EpisodeRecorder(out / "demo.rrd", first_seed=int(seed), name=f"demo: reverse alarm, seed {int(seed)}")
    trace = Trace()
    try:
        from tasks.reverse_alarm import PAPER_CAR

        env = make_env(TASK, profile=profile, **PAPER_CAR)  # the paper's car: R at 15 deg, the alarm at once
        try:
            from policies import make_policy

            policy = make_policy("scripted", env)

            def hook(*args):
                trace(*args)
                trace.waiting.append((policy.waiting, policy.maskers) if args[2] > 0 else (None, ()))
                recorder(*args)

            record = run_episode(env, policy, int(seed), step_callback=hook)
        finally:
            env.close()
    finally:
        recorder.close()
    threshold = float(policy.threshold)
    lateral = tuple(float(x) for x in policy.lateral_range_deg)
    elevation = tuple(float(x) for x in policy.elevation_deg)
    text, moments = narrate(trace, record, threshold=threshold, lateral_range_deg=lateral,
                            success_window_s=float(env.success_window_s), seed=int(seed), profile=profile,
                            elevation_deg=elevation)
    title = (f"ReverseAlarm, scripted policy, seed {seed}, {profile} models: "
             f"{record['outcome'].replace('_', ' ')}")
    figure(trace, moments, out / "demo.png", threshold=threshold, lateral_range_deg=lateral, title=title,
           elevation_deg=elevation)
    audio = np.concatenate(trace.audio, axis=1) if trace.audio else np.zeros((2, 0), np.float32)
    write_wav(out / "demo.wav", audio, SAMPLE_RATE)
    write_text(out / "demo.json", json.dumps({"task": TASK, "policy": "scripted", "profile": profile, "seed": int(seed),
                                              "record": record, "moments": moments, "narration": text.splitlines()},
                                             indent=1) + "\n")
    files = ", ".join(str(out / f"demo.{ext}") for ext in ("png", "rrd", "wav", "json"))
    return f"{text}\nwrote {files}\nview the recording with: acoustic-sim play {out / 'demo.rrd'}"


__all__ = ["LABEL", "Trace", "figure", "narrate", "run_demo", "side_words"]
