"""REPORT.md and the localization figures of ``eval paper``, generated from its JSON files.

The README's "Paper results" section is the report's tables, copied by
``acoustic-sim eval readme`` (:func:`update_readme`) between the markers
``<!-- paper:begin -->`` and ``<!-- paper:end -->``; a test checks that they agree with
the committed ``results/paper`` files, so no number is typed by hand.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from acoustic_sim.errors import ConfigError  # noqa: E402
from acoustic_sim.files import atomic_path, write_text  # noqa: E402

METHODS = ("ssdenet", "ssdenet_sum", "music", "gcc_phat")
"""The simulation table's methods, as JSON keys (a run from before ``ssdenet_sum`` lacks it)."""
LABELS = {"ssdenet": "SSDENet", "ssdenet_sum": "SSDENet, sum", "ssdenet-sum": "SSDENet, sum", "music": "MUSIC",
          "gcc_phat": "GCC-PHAT", "gcc-phat": "GCC-PHAT", "ssdenet-wavefront": "SSDENet, first wavefront"}
FUSION_NOTE = ("*SSDENet* fuses the valid bins of a frame by n times their geometric mean (the default, "
               "`acoustic_sim.auditory.ssdenet.FUSIONS`: a bin that is confidently wrong cannot outvote the "
               "others); *SSDENet, sum* is the paper's equation, P(d) = sum_i P(d, w_i), with the same networks "
               "and bins. Frames are summed in both.")
"""Said under the simulation table: what the two SSDENet columns are."""
BEGIN, END = "<!-- paper:begin -->", "<!-- paper:end -->"


def _load(out: Path, name: str) -> dict:
    path = out / name
    if not path.is_file():
        raise ConfigError(f"{path} is missing: run `acoustic-sim eval paper --out {out}` first")
    return json.loads(path.read_text())


def _fmt(v, digits: int = 1) -> str:
    return "n/a" if v is None else f"{v:.{digits}f}"


SIM_MAX_DEG = 15.0
"""Target: SSDENet's mean error in simulation for white noise, square and sawtooth waves (deg)."""

ROOM_LR_MIN, ROOM_TB_MIN = 0.98, 0.85
"""Targets: left-right and top-bottom accuracy in the room."""

ROOM_LABELS = {"ssdenet": "on the frames", "ssdenet-wavefront": "first wavefront"}
"""SSDENet's two room estimators, as the targets table names them."""

DETECTION_F1_MIN = 0.90
"""Target: MelCNN's held-out macro F1."""

WHY = {
    "simulation": "`acoustic_sim.auditory.ssdenet.recipes.PAPER` (its docstring: which bins the networks have, and "
                  "what was measured for the signals whose harmonics meet few of them)",
    "room": "`acoustic_sim.experiments.localization` (its docstring: why the frames lose the median plane in the "
            "reverberant room) and `ROOM_ONSET_WINDOWS` there",
}
"""Where a missed target's reasons are written down, per experiment."""


def targets(loc: dict, det: dict) -> list[dict]:
    """The project's targets for a run, each ``{"target", "result", "met", "experiment"}``.

    ``met`` is a bool. The room's accuracies are SSDENet's on the frames (the paper's
    method) and on the first wavefront (the streaming pipeline's rule): met when either
    meets it, and ``met_by`` lists which.
    """
    sim = loc["simulation"]
    below = sum(r["ssdenet_deg"] < r["music_deg"] for r in sim)
    broadband = [r for r in sim if r["signal"] in ("white_noise", "square", "sawtooth")]
    worst = max(broadband, key=lambda r: r["ssdenet_deg"])
    over = [r for r in broadband if r["ssdenet_deg"] > SIM_MAX_DEG]

    def name(r):
        return r["signal"] if r["f0_hz"] is None else f"{r['signal']} {r['f0_hz']:.0f} Hz"

    rows = [
        {"target": "simulation: SSDENet's mean error below MUSIC's, every signal",
         "result": f"{below} of {len(sim)}", "met": below == len(sim), "experiment": "simulation"},
        {"target": f"simulation: SSDENet's mean error at most {SIM_MAX_DEG:.0f} deg for white noise, square and sawtooth",
         "result": ("over: " + ", ".join(f"{name(r)} {r['ssdenet_deg']:.1f} deg" for r in over) if over
                    else f"worst: {name(worst)} {worst['ssdenet_deg']:.1f} deg"),
         "met": not over, "experiment": "simulation"},
    ]
    room = loc["room"]
    for key, floor, what in (("lr_accuracy", ROOM_LR_MIN, "left-right"), ("tb_accuracy", ROOM_TB_MIN, "top-bottom")):
        ours = {m: v for m, v in room[key].items() if m in ROOM_LABELS}
        ok = [m for m, v in ours.items() if v >= floor]
        rows.append({"target": f"room: SSDENet's {what} accuracy at least {floor:.2f}",
                     "result": ", ".join(f"{ROOM_LABELS[m]} {v:.3f}" for m, v in ours.items()),
                     "met": bool(ok), "met_by": [ROOM_LABELS[m] for m in ok], "experiment": "room"})
    rows.append({"target": f"detection: MelCNN's macro F1 at least {DETECTION_F1_MIN:.2f}",
                 "result": f"{det['f1_macro']:.3f}", "met": det["f1_macro"] >= DETECTION_F1_MIN, "experiment": "detection"})
    return rows


def _target_lines(loc: dict, det: dict) -> list[str]:
    rows = targets(loc, det)
    lines = ["**Against the targets** (the frame time, training time and memory targets are "
             "`acoustic-sim bench pipeline`'s):", "", "| target | result | met |", "|---|---|---|"]
    def partly(r):  # met by some of SSDENet's estimators only
        return "met_by" in r and r["met"] and len(r["met_by"]) < len(ROOM_LABELS)

    for r in rows:
        met = ("yes (" + " and ".join(r["met_by"]) + " only)") if partly(r) else ("yes" if r["met"] else "no")
        lines.append(f"| {r['target']} | {r['result']} | {met} |")
    missed = sorted({r["experiment"] for r in rows if (not r["met"] or partly(r)) and r["experiment"] in WHY})
    if missed:
        lines += ["", "Where a target is missed or met by one method only, the reasons and what was tried are in "
                  + "; ".join(WHY[e] for e in missed) + "."]
    return lines + [""]


def _methods(loc: dict) -> list[str]:
    """The simulation's methods present in a run (:data:`METHODS`, in order)."""
    return [m for m in METHODS if f"{m}_deg" in loc["simulation"][0]]


def tables(out) -> str:
    """The Markdown tables of a finished run (the body of REPORT.md and the README section)."""
    out = Path(out)
    pinna, ild, loc, det = (_load(out, n) for n in ("pinna.json", "hrtf_ild_ipd.json", "localization.json", "detection.json"))
    lines = _target_lines(loc, det)
    methods = _methods(loc)
    w, wo = pinna["with_pinna"], pinna["without_pinna"]
    lines += [
        "**Pinna (median plane, left ear).** "
        f"With pinnae ({w['hrtf']}): a notch at {w['notch_count']} of {len(w['notch_hz'])} elevations, "
        f"{_fmt(w['notch_range_hz'][0], 0) if w['notch_range_hz'] else 'n/a'}-"
        f"{_fmt(w['notch_range_hz'][1], 0) if w['notch_range_hz'] else 'n/a'} Hz, response spread "
        f"{w['elevation_spread_db']} dB over elevation; without ({wo['hrtf']}): {wo['notch_count']} notches, "
        f"spread {wo['elevation_spread_db']} dB.",
        "",
        "| ILD range (natural log) | " + " | ".join(f"{r['frequency_hz']:.1f} Hz" for r in ild["ild_range"]) + " |",
        "|---|" + "---|" * len(ild["ild_range"]),
        "| ours (max abs ILD) | " + " | ".join(f"{r['ours']:.2f}" for r in ild["ild_range"]) + " |",
        "| paper | " + " | ".join("-" if r["paper"] is None else f"{r['paper']:.2f}" for r in ild["ild_range"]) + " |",
        "",
        *_median_plane_lines(ild),
        f"**Localization in simulation** (mean angular error in deg over {loc['directions']} directions, "
        f"{loc['hrtf']}, `{loc['profile']}` models):",
        "",
        "| signal | f0 (Hz) | " + " | ".join(LABELS[m] for m in methods) + " |",
        "|---|---|" + "---|" * len(methods),
    ]
    for row in loc["simulation"]:
        f0 = "-" if row["f0_hz"] is None else f"{row['f0_hz']:.0f}"
        lines.append(f"| {row['signal']} | {f0} | " + " | ".join(_fmt(row[f"{m}_deg"]) for m in methods) + " |")
    if "ssdenet_sum" in methods:
        lines += ["", FUSION_NOTE]
    room = loc["room"]
    keys = list(room["horizontal_mean_deg"])
    lines += [
        "",
        f"**Localization in the {room['room']} room** (white noise {room['level_db_spl'][0]:.0f}-"
        f"{room['level_db_spl'][1]:.0f} dB SPL at {room['distance_m']} m; models from {room['trained_on']}"
        + (f", measured in the {room['measured_in']} room with {room['measured_taps']} taps" if "measured_taps" in room else "")
        + f"; {room.get('trials_per_angle', 1)} trial(s) per angle):",
        "",
        "| metric | " + " | ".join(LABELS.get(k, k) for k in keys) + " |",
        "|---|" + "---|" * len(keys),
    ]
    for metric, digits in (("horizontal_mean_deg", 1), ("median_mean_deg", 1), ("lr_accuracy", 3), ("tb_accuracy", 3),
                           ("front_back_confusion", 3)):
        lines.append(f"| {metric} | " + " | ".join(_fmt(room[metric][k], digits) for k in keys) + " |")
    if "ssdenet-wavefront" in keys:
        n = int(room.get("wavefront_windows", 1))
        where = "a 1.75 ms window" if n == 1 else f"{n} windows of 1.75 ms, 1 ms apart,"
        lines += [
            "",
            "The paper's methods (SSDENet with either fusion, MUSIC, GCC-PHAT) use the frames after the loudspeaker "
            "has started; *SSDENet, first wavefront* "
            f"is the same bank (product fusion) on {where} at the loudspeaker's onset (the streaming pipeline's precedence rule, "
            "`acoustic_sim.experiments.localization.first_wavefront`), which most of the lab's reflections reach too late to enter.",
        ]
    lines += [
        "",
        f"**Detection** (MelCNN, `{det['profile']}`, {det['n_examples']} windows with mixtures, noise and "
        f"reverberation, held out from the training and from the recipe's choices): macro F1 **{det['f1_macro']:.3f}** (paper: {det['paper_f1']}).",
        "",
        "| class | precision | recall | F1 | support |",
        "|---|---|---|---|---|",
    ]
    for c, v in det["per_class"].items():
        lines.append(f"| {c} | {v['precision']:.3f} | {v['recall']:.3f} | {v['f1']:.3f} | {v['support']} |")
    return "\n".join(lines) + "\n"


def localization_figures(out) -> list[str]:
    """Bar chart of the simulation errors and per-angle room errors; returns the file names."""
    out = Path(out)
    loc = _load(out, "localization.json")
    rows = loc["simulation"]
    names = [r["signal"] if r["f0_hz"] is None else f"{r['signal']}\n{r['f0_hz']:.0f}" for r in rows]
    fig, ax = plt.subplots(figsize=(11, 3.6))
    x = np.arange(len(rows))
    methods = _methods(loc)
    width = 0.8 / len(methods)
    for i, m in enumerate(methods):
        ax.bar(x + (i - (len(methods) - 1) / 2) * width, [r[f"{m}_deg"] for r in rows], width=width, label=LABELS[m])
    ax.axhline(90, color="grey", lw=0.8, ls=":", label="chance (90 deg)")
    ax.set_xticks(x, names, fontsize=7)
    ax.set_ylabel("mean angular error (deg)")
    ax.set_title(f"Localization in simulation ({loc['hrtf']}, {loc['directions']} directions)")
    ax.set_ylim(0, 118)  # room for the legend above the bars near chance
    ax.legend(fontsize=8, ncols=len(methods) + 1, loc="upper right")
    fig.tight_layout()
    with atomic_path(out / "localization_simulation.png") as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)

    room = loc["room"]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4))
    for ax, plane, coord in ((axes[0], "horizontal", "azimuth_deg"), (axes[1], "median", "elevation_deg")):
        for m, per in room[f"{plane}_per_angle"].items():
            if plane == "median":
                xs = [p["elevation_deg"] if abs(p["azimuth_deg"]) < 90 else 180 - p["elevation_deg"] for p in per]
            else:
                xs = [p[coord] for p in per]
            order = np.argsort(xs)
            ax.plot(np.asarray(xs)[order], np.asarray([p["error_deg"] for p in per])[order], "o-", ms=3, label=LABELS.get(m, m))
        ax.set_xlabel("azimuth (deg)" if plane == "horizontal" else "polar angle (deg, 0 front, 90 up, 180 back)")
        ax.set_ylabel("error (deg)")
        ax.set_title(f"{plane} plane")
        ax.legend(fontsize=7)
    fig.suptitle(f"Localization in the {room['room']} room")
    fig.tight_layout()
    with atomic_path(out / "localization_room.png") as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return ["localization_simulation.png", "localization_room.png"]


def _median_plane_lines(ild: dict) -> list[str]:
    """What the interaural features hold on the median plane (absent in older files)."""
    mp = ild.get("median_plane")
    if mp is None:
        return []
    return [
        f"**Interaural differences on the median plane** ({ild['hrtf']}, {mp['directions']} directions, "
        f"{mp['band_hz'][0]:.0f}-{mp['band_hz'][1]:.0f} Hz): max |ILD| {mp['max_abs_ild_db']:.3g} dB, max |IPD| "
        f"{mp['max_abs_ipd_rad']:.3g} rad. {mp['consequence']}",
        "",
    ]


def write_report(out) -> Path:
    """Write the figures and REPORT.md of a finished run; returns the report's path."""
    out = Path(out)
    figures = localization_figures(out)
    summary = _load(out, "summary.json")
    body = [
        "# Omura et al. 2022, reproduced in simulation",
        "",
        f"Generated by `acoustic-sim eval paper --out {out}{' --quick' if summary['quick'] else ''}` "
        f"(seed {summary['seed']}, ears: {summary['hrtf']}, models: `{summary['profile']}`; "
        f"{summary['timings']['total_s']:.0f} s). Do not edit: rerun the command.",
        "",
        tables(out),
        "![pinna](pinna.png)",
        "",
        "![ILD](hrtf_ild.png)",
        "",
        "![IPD](hrtf_ipd.png)",
        "",
        *[f"![{f[:-4]}]({f})\n" for f in figures],
    ]
    path = out / "REPORT.md"
    write_text(path, "\n".join(body))
    return path


def readme_section(results_dir, image_prefix: str) -> str:
    """The README's generated section: the tables and the figures of ``results_dir``."""
    figs = ["pinna.png", "hrtf_ild.png", "localization_simulation.png", "localization_room.png"]
    return "\n".join([BEGIN, tables(results_dir), *[f"![{f[:-4]}]({image_prefix}/{f})\n" for f in figs], END])


def replace_section(readme, begin: str, end: str, section: str) -> bool:
    """Replace the text from ``begin`` to ``end`` (markers included) in ``readme`` with
    ``section``; returns True when the file changed."""
    readme = Path(readme)
    text = readme.read_text()
    if begin not in text or end not in text:
        raise ConfigError(f"{readme} has no {begin} ... {end} section to fill")
    start, stop = text.index(begin), text.index(end) + len(end)
    new = text[:start] + section + text[stop:]
    if new != text:
        write_text(readme, new)
    return new != text


def update_readme(readme, results_dir, image_prefix: str = "results/paper") -> bool:
    """Replace the README's generated section; returns True when the file changed."""
    return replace_section(readme, BEGIN, END, readme_section(results_dir, image_prefix))


def write_json(path, data) -> None:
    """Write ``data`` as JSON (no NaN) through a temporary file, so a reader never sees half a file."""
    path = Path(path)
    write_text(path, json.dumps(data, indent=1, allow_nan=False) + "\n")
