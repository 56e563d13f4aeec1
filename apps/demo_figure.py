"""``demo.png``: the demo episode as the paper's task figures draw one.

Left and right mel spectrograms, the class probabilities (shaded where the lever waited for
quiet), and the reverse alarm's estimated lateral angle from the turned head over time (the
angle the scripted policy's rule reads, its accepted band shaded) with the true ones of the
alarm and of any beeping distractor; events are vertical lines.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acoustic_sim.files import atomic_path
from acoustic_sim.frames import FRAME_RATE
from apps.demo_trace import LABEL, Trace, alarm_estimates


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
    p, _, has, lat, el = alarm_estimates(trace)
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


__all__ = ["figure"]
