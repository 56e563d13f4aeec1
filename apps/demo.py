"""What ``make demo`` runs: one ReverseAlarm episode with the scripted policy, told in words.

The robot sits in the car cabin with its left hand on the gearshift
(``acoustic_sim/ReverseAlarm-v0``, :mod:`tasks.reverse_alarm`), in the paper's car
(``PAPER_CAR``: R at 15 deg, the alarm as R engages). The scripted policy
(:mod:`policies.scripted`) pushes the lever toward R; entering R starts the reverse alarm in
front of the head; the policy lets go once the alarm is heard *from the front*, while
distractors (another vehicle's beeper behind or beside, a horn, the radio) try to fool it.
The episode runs through the episode runner (:func:`apps.runner.run_episode`), whose
step hook feeds both the rerun recording and this module's trace.

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

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import atomic_path, check_writable_folder, write_text, write_wav
from acoustic_sim.frames import (FRAME_RATE, SAMPLE_RATE, head_to_body_azimuth, head_to_body_elevation, in_lateral_region,
                                 lateral_deg)

TASK = "reverse-alarm"
LABEL = "reverse_alarm"
PROFILES = ("fast", "paper")


@dataclasses.dataclass
class Trace:
    """What the episode looked like, step by step (the runner's step hook fills it).

    Attributes
    ----------
    t : list of float
        Seconds since the episode's first observation, per step (0 is the reset).
    prob : list of numpy.ndarray
        (6,) class probabilities of the observation.
    direction : list of numpy.ndarray
        (6, 3) estimated direction per class (head frame; zeros: no estimate).
    neck : list of numpy.ndarray
        (2,) the neck's yaw and pitch (rad, proprioception) per step: the head frame's turn
        on the body. Empty (a trace made by hand): the head looks straight ahead.
    confidence : list of numpy.ndarray
        (6,) confidence of each estimate.
    true_az : list of dict
        Per step, the true azimuth (deg, car frame) of each sound playing, by source name
        (ground truth from ``info``, used only to tell the reader what was really there).
    true_lateral : list of dict
        The same for the true lateral angle from the turned head (deg, + left: the angle the
        policy's rule reads; :func:`~acoustic_sim.frames.lateral_deg`).
    labels : dict
        Source name -> sound class of every source that played.
    audio : list of numpy.ndarray
        (2, 705 | 706) digital ear blocks of steps 1, 2, ...
    events : list of tuple
        (seconds since the start, ``info`` event dict).
    start_s : float
        Project-clock time (s) of the episode's first observation (``env.start_s``).
    waiting : list of tuple
        Per step, why the policy's lever stood (``None``, ``"listening"``, ``"masked"`` or
        ``"settling"``, :class:`policies.scripted.ScriptedReverseAlarm`) and the classes that
        masked; empty when the hook that fills it was not given the policy.
    """

    t: list = dataclasses.field(default_factory=list)
    prob: list = dataclasses.field(default_factory=list)
    direction: list = dataclasses.field(default_factory=list)
    neck: list = dataclasses.field(default_factory=list)
    confidence: list = dataclasses.field(default_factory=list)
    true_az: list = dataclasses.field(default_factory=list)
    true_lateral: list = dataclasses.field(default_factory=list)
    labels: dict = dataclasses.field(default_factory=dict)
    audio: list = dataclasses.field(default_factory=list)
    events: list = dataclasses.field(default_factory=list)
    start_s: float = 0.0
    waiting: list = dataclasses.field(default_factory=list)

    def wait_runs(self) -> list[tuple[int, int]]:
        """(first, last) steps of each run in which the lever waited for quiet (``masked`` or
        ``settling``, not ``listening``)."""
        return _runs(np.array([w[0] in ("masked", "settling") for w in self.waiting], bool))

    def necks(self) -> list:
        """:attr:`neck` per step, the head straight ahead where the trace has none."""
        return self.neck if self.neck else [np.zeros(2)] * len(self.direction)

    def __call__(self, env, episode, step, obs, reward, terminated, truncated, info) -> None:
        env = env.unwrapped
        if step == 0:
            self.start_s = float(env.start_s)
        self.t.append(float(info["time_s"]) - self.start_s)
        self.prob.append(np.array(obs["class_prob"], dtype=np.float64))
        self.direction.append(np.array(obs["class_dir"], dtype=np.float64).reshape(-1, 3))
        neck = np.array(obs["joint_pos"][:2], dtype=np.float64)
        self.neck.append(neck)
        self.confidence.append(np.array(obs["class_conf"], dtype=np.float64))
        az, lat = {}, {}
        for snd in info["sounding"]:
            az[snd["source"]] = car_azimuth_deg(snd["direction"], neck)
            lat[snd["source"]] = lateral_deg(snd["direction"])
            self.labels[snd["source"]] = snd["label"]
        self.true_az.append(az)
        self.true_lateral.append(lat)
        if step > 0:
            self.audio.append(np.array(env.last_audio, dtype=np.float32))
        for e in info["events"]:
            self.events.append((float(e["time_s"]) - self.start_s, dict(e)))


def azimuth_deg(v) -> float:
    """Azimuth (deg, -180..180, + left) of a vector."""
    return math.degrees(math.atan2(float(v[1]), float(v[0])))


def car_azimuth_deg(v_head, neck=(0.0, 0.0), *, mirror: bool = False) -> float:
    """Azimuth (deg, + left) in the car's frame of a head-frame vector, the neck turned by
    ``neck`` = (yaw, pitch) rad; ``mirror``: of its front-back mirror image through the
    head's interaural axis (what the ears cannot tell it from)."""
    return math.degrees(head_to_body_azimuth(v_head, float(neck[0]), float(neck[1]), mirror=mirror))


def side_words(az: float) -> str:
    """Where an azimuth (deg, + left) is, in words: in front, front left, left, behind, ..."""
    a = (az + 180.0) % 360.0 - 180.0
    names = ["behind", "behind on the right", "on the right", "in front on the right", "in front",
             "in front on the left", "on the left", "behind on the left", "behind"]
    return names[int(np.floor((a + 180.0 + 22.5) / 45.0))]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) indices of the runs of True in a boolean array."""
    idx = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return [(int(a), int(b) - 1) for a, b in zip(idx[::2], idx[1::2])]


def _alarm_estimates(trace: Trace) -> tuple[np.ndarray, ...]:
    """Per step: the reverse alarm's probability, its estimated direction (head frame),
    whether it has one, and that estimate's lateral angle from the head and elevation in the
    car's frame (deg; NaN without an estimate)."""
    from acoustic_sim.acoustics.sounds import SOUND_CLASSES

    k = SOUND_CLASSES.index(LABEL)
    p = np.array([x[k] for x in trace.prob])
    d = np.array([x[k] for x in trace.direction])
    has = np.linalg.norm(d, axis=1) > 0.5
    lat = np.array([lateral_deg(v) if h else np.nan for v, h in zip(d, has)])
    el = np.array([math.degrees(head_to_body_elevation(v, float(n[1]))) if h else np.nan
                   for v, n, h in zip(d, trace.necks(), has)])
    return p, d, has, lat, el


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
    p, d, has, lat, el = _alarm_estimates(trace)
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
    for a, b in _runs(heard & (t < (onset if onset is not None else np.inf))):
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


def figure(trace: Trace, moments: dict, path: Path, *, threshold: float, lateral_range_deg: tuple, title: str,
           elevation_deg: tuple = (-90.0, 90.0)) -> None:
    """``demo.png``: mel spectrograms, the class probabilities and the alarm's estimated
    lateral angle from the head (the angle the policy's rule reads).

    Parameters
    ----------
    trace : Trace
    moments : dict
        From :func:`narrate`: the alarm's start, its recognition and the release are marked.
    path : pathlib.Path
        The PNG to write (parent folders are created).
    threshold : float
        The policy's probability threshold (a dotted line; estimates above it in red).
    lateral_range_deg : tuple of float
        The lateral angles (deg, + left, from the turned head) the policy accepts as the
        alarm's (shaded).
    title : str
    elevation_deg : tuple of float
        The region's elevations (deg, car frame, the policy's): estimates outside them are
        drawn as crosses (rejected whatever their lateral angle).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acoustic_sim.acoustics.sounds import SOUND_CLASSES
    from acoustic_sim.auditory.features import MEL_FMAX_HZ, MEL_FMIN_HZ, N_MELS, hz_to_mel, mel_power
    from acoustic_sim.auditory.frontend import analyze

    k = SOUND_CLASSES.index(LABEL)
    t = np.asarray(trace.t)
    audio = np.concatenate(trace.audio, axis=1) if trace.audio else np.zeros((2, 0), np.float32)
    frames = analyze(audio)
    mel_db = 10.0 * np.log10(np.maximum(mel_power(frames.spectra), 1e-20))  # (K, 2, N_MELS)
    top = float(mel_db.max()) if mel_db.size else 0.0
    fig, axes = plt.subplots(4, 1, figsize=(10, 9), sharex=True, constrained_layout=True,
                             gridspec_kw={"height_ratios": [2, 2, 1.2, 2]})
    ticks_hz = [f for f in (100, 250, 500, 1000, 2000, 4000, 8000, 16000) if MEL_FMIN_HZ <= f <= MEL_FMAX_HZ]
    m0, m1 = hz_to_mel(MEL_FMIN_HZ), hz_to_mel(MEL_FMAX_HZ)
    tick_pos = [(hz_to_mel(f) - m0) / (m1 - m0) * (N_MELS - 1) for f in ticks_hz]
    image = None
    for ax, ear, name in ((axes[0], 0, "left ear"), (axes[1], 1, "right ear")):
        if len(frames):
            image = ax.imshow(mel_db[:, ear, :].T - top, origin="lower", aspect="auto", cmap="magma", vmin=-80, vmax=0,
                              extent=(frames.time_s[0] - 1 / FRAME_RATE, frames.time_s[-1], -0.5, N_MELS - 0.5),
                              interpolation="nearest")
        ax.set_yticks(tick_pos, [f"{f / 1000:g}" for f in ticks_hz])
        ax.set_ylabel(f"{name}\nfrequency (kHz)")
    if image is not None:
        fig.colorbar(image, ax=axes[:2], label="mel band power (dB re loudest)", shrink=0.8, fraction=0.03, pad=0.01)
    p, _, has, lat, el = _alarm_estimates(trace)
    axes[2].plot(t, p, color="tab:red", lw=1.5, label="reverse alarm")
    for j, c in enumerate(SOUND_CLASSES):
        if j != k:
            axes[2].plot(t, [x[j] for x in trace.prob], lw=0.8, alpha=0.6, label=c.replace("_", " "))
    axes[2].axhline(threshold, color="k", lw=0.6, ls=":")
    # The lever's waits for quiet (the policy's reason per step, when the trace has it).
    for n, (a, b) in enumerate(trace.wait_runs()):
        axes[2].axvspan(t[a], t[min(b + 1, len(t) - 1)], color="tab:blue", alpha=0.12, lw=0,
                        label="lever waits for quiet" if n == 0 else None)
    axes[2].set_ylim(-0.02, 1.02)
    axes[2].set_ylabel("class\nprobability")
    axes[2].legend(loc="upper left", fontsize=7, ncol=3)
    lo, hi = lateral_range_deg
    axes[3].axhspan(lo, hi, color="tab:green", alpha=0.1, lw=0,
                    label=f"alarm's region ({lo:+g} to {hi:+g} deg: in front, or its mirror behind)")
    off = np.array([h and not elevation_deg[0] <= e <= elevation_deg[1] for h, e in zip(has, el)], dtype=bool)
    on = has & (p >= threshold)
    axes[3].scatter(t[has & ~on & ~off], lat[has & ~on & ~off], s=6, color="0.6", label=f"estimate, p < {threshold:g}")
    axes[3].scatter(t[on & ~off], lat[on & ~off], s=10, color="tab:red", label=f"estimate, p >= {threshold:g}")
    if np.any(off):
        axes[3].scatter(t[off], lat[off], s=14, marker="x", lw=0.8, color=np.where(on[off], "tab:red", "0.6"),
                        label=f"estimate outside the region's elevations ({elevation_deg[0]:+g} to {elevation_deg[1]:+g} deg)")
    for src, style in _true_tracks(trace):
        ys = np.array([x.get(src, np.nan) for x in trace.true_lateral]) if trace.true_lateral else np.full(t.size, np.nan)
        axes[3].plot(t, ys, **style)
    axes[3].set_ylim(-92, 92)
    axes[3].set_yticks([-90, -45, 0, 45, 90], ["-90\nright", "-45", "0", "+45", "+90\nleft"])
    axes[3].set_ylabel("reverse alarm: lateral angle\nfrom the head (deg; 0: its\nmedian plane)")
    axes[3].set_xlabel("time since the episode's start (s)")
    axes[3].legend(loc="lower left", fontsize=7, ncol=2)
    marks = [("alarm_start_s", "alarm starts", "tab:red"), ("recognized_s", "recognized", "tab:orange"),
             ("release_s", "hand lets go", "tab:green")]
    t_end = max(float(t[-1]) if t.size else 1.0, 0.5)
    for row, (key, label, color) in enumerate(marks):
        x = moments.get(key)
        if x is None:
            continue
        for ax in axes:
            ax.axvline(x, color=color, lw=1.2, ls="--")
        right = x > 0.85 * t_end  # near the end: write the label to the left of its line
        axes[0].text(x, N_MELS - 2 - 22 * row, f"{label} " if right else f" {label}", color=color, va="top",
                     ha="right" if right else "left", fontsize=8, bbox={"facecolor": "white", "alpha": 0.8, "lw": 0, "pad": 1})
    for te, e in trace.events:
        if e["kind"] == "distractor":
            for ax in axes[2:]:
                ax.axvline(te, color="0.4", lw=0.8, ls=":")
            axes[3].text(te, 88, f"{e['label'].replace('_', ' ')} ", color="0.3", va="top", ha="right", fontsize=7,
                         rotation=90)
    axes[0].set_title(title, fontsize=10)
    axes[3].set_xlim(0.0, t_end)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110)
    finally:
        plt.close(fig)


def _true_tracks(trace: Trace) -> list[tuple[str, dict]]:
    """The beeping sources (the car's alarm, another vehicle's beeper) and how to draw their
    true azimuth."""
    out = []
    for src, label in trace.labels.items():
        if label != LABEL:
            continue
        if src == "alarm":
            out.append((src, {"color": "k", "lw": 1.2, "label": "true: the car's alarm"}))
        else:
            out.append((src, {"color": "tab:purple", "lw": 1.2, "ls": "--", "label": "true: another vehicle's beeper"}))
    return out


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


__all__ = ["Trace", "figure", "narrate", "run_demo", "side_words"]
