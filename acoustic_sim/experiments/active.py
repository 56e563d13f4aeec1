"""``acoustic-sim eval active``: does one head turn resolve front and back? (issue 33)

Each trial plays one sound (white noise or one of the six classes) from a direction drawn
from the seed, in the ``lab`` room (1.5 m away, as the paper's room experiment) and in the
``car_cabin`` (0.8 m, or less where a wall is nearer). The head starts facing the room's
+x and either stays still or, :data:`TURN_START_S` after the sound starts, turns once about
the vertical by 10, 15, 30 or 45 deg (left or right, drawn) at :data:`TURN_SPEED_DEG_S`,
then holds. The sound lasts :data:`SOUND_S`.

Every frame after the sound's start gives SSDENet's existence map over the direction grid
from its valid bins within the sound's characteristic bins (all the bank's bins for white
noise), fused by the pipeline's product: the paper's rule on the frames. Two estimates are
scored at the sound's end:

- ``static``: the sum of the frames' maps in the head frame, its argmax (the pipeline's
  estimate today); with a turning head it would smear, so it is scored on the still head.
- ``tracked``: :class:`~acoustic_sim.auditory.tracker.DirectionTracker` fed with every frame
  and the head's pose at the frame's centre, its world-frame peak.

Scores per room and condition: the **front-back confusion rate** (the estimate nearer to
the truth's mirror image through the head's interaural axis than to the truth, at the final
pose; over sources at least :data:`FRONTAL_MARGIN_DEG` from the frontal plane, where the
question has an answer), the **mean azimuth error** (world frame, every trial, confusions
included), the mean angular error, the share decided and the median **time to a decision**
(from the sound's start to the first frame at which the tracker's front-back decision
stands, :attr:`~acoustic_sim.auditory.tracker.TrackedDirection.decided`).

The evidence is the streaming pipeline's (:class:`~acoustic_sim.auditory.pipeline.AuditoryPipeline`
attending to the sound, :meth:`~acoustic_sim.auditory.pipeline.AuditoryPipeline.attend`), by
default with ``precedence="wavefront+coherence"``: the first wavefront at onsets and, between
them, the bins whose interaural coherence shows the direct sound (a continuous noise has one
onset only). What each rule gave is in docs/notes/active_hearing.md.

The scene (rendering, the head's turn, feeding the pipeline) is in
:mod:`~acoustic_sim.experiments.active_scene`; the two-source scenes (``pairs.json``) in
:mod:`~acoustic_sim.experiments.active_pairs`.

``--quick`` runs 3 + 1 directions, two sounds, turns of 0 and 30 deg and one two-source scene
per room with the small models:
every file with every key, for the tests. Its numbers are not the experiment's.
"""

from __future__ import annotations

import math
import time

import numpy as np

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.auditory.pipeline import PRECEDENCE, AuditoryPipeline
from acoustic_sim.auditory.tracker import DirectionTracker
from acoustic_sim.directions import DirectionGrid, angular_error_deg
from acoustic_sim.errors import ConfigError
from acoustic_sim.experiments.active_pairs import (N_PAIRS, PAIR_MIN_SEPARATION_DEG, PAIR_ROOMS, PAIR_TOLERANCE_DEG,
                                                   PAIR_TURN_DEG, PAIRS, draw_pair, pairs_summary, pairs_table, run_pair,
                                                   run_pairs, summarize_pairs)
from acoustic_sim.experiments.active_scene import (DISTANCE_M, LEAD_S, LEVEL_DB_SPL, SOUND_S, TURN_SPEED_DEG_S, TURN_START_S,
                                                   WALL_CLEARANCE_M, head_yaw_deg, listen, render_scene, render_trial,
                                                   source_distance)
from acoustic_sim.experiments.localization import noise_floor
from acoustic_sim.files import check_writable_folder
from acoustic_sim.frames import vec_to_sph
from acoustic_sim.progress import progress_bar

ROOMS = ("lab", "car_cabin")
"""The rooms of the experiment."""

TURNS_DEG = (0.0, 10.0, 15.0, 30.0, 45.0)
"""Head turns of the experiment (deg; 0 is the still head)."""

FRONTAL_MARGIN_DEG = 10.0
"""Front-back confusions are counted over sources at least this far (deg) from the frontal
plane (the head's x = 0 at the final pose)."""

PRECEDENCE_DEFAULT = "wavefront+coherence"
"""The pipeline's evidence rule in the experiment (:data:`~acoustic_sim.auditory.pipeline.PRECEDENCE`)."""

N_HORIZONTAL, N_OFF_PLANE = 100, 50
"""Directions per room: on the horizontal plane and off it (elevation 10-60 deg up or
10-40 deg down, the HRTF's coverage)."""


def draw_directions(rng: np.random.Generator, n_horizontal: int, n_off_plane: int) -> np.ndarray:
    """World-frame unit vectors (n, 3): ``n_horizontal`` azimuths uniform on the circle,
    then ``n_off_plane`` with a uniform azimuth and an elevation of 10-60 deg up or 10-40 deg
    down (equal odds)."""
    az = rng.uniform(-180.0, 180.0, n_horizontal + n_off_plane)
    el = np.zeros(az.size)
    up = rng.random(n_off_plane) < 0.5
    el[n_horizontal:] = np.where(up, rng.uniform(10.0, 60.0, n_off_plane), -rng.uniform(10.0, 40.0, n_off_plane))
    a, e = np.deg2rad(az), np.deg2rad(el)
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=1)


def _mirror_nearer(est: np.ndarray, truth: np.ndarray) -> bool:
    mirror = truth * np.array([-1.0, 1.0, 1.0])
    return float(est @ mirror) > float(est @ truth)


def _azimuth_error(a: np.ndarray, b: np.ndarray) -> float:
    return float(abs((vec_to_sph(a)[0] - vec_to_sph(b)[0] + 180.0) % 360.0 - 180.0))


def _scores(est_world, truth_world, truth_head, est_head) -> dict:
    return {
        "confusion": _mirror_nearer(np.asarray(est_head), np.asarray(truth_head)),
        "azimuth_error_deg": round(_azimuth_error(np.asarray(est_world), np.asarray(truth_world)), 2),
        "error_deg": round(float(angular_error_deg(est_world, truth_world)), 2),
    }


def run_trial(pipe: AuditoryPipeline, hrtf: HRTF, room: str, direction: np.ndarray, sound: str, turn_deg: float,
              rng: np.random.Generator) -> dict:
    """One trial's record: the truth, the pipeline's head-frame estimate at the sound's end
    (the still head only), the tracker's world-frame estimate and its decision time.

    ``pipe`` has a tracker and attends to ``sound`` (:meth:`AuditoryPipeline.attend`)."""
    sign = 1.0 if rng.random() < 0.5 else -1.0
    audio, poses = render_trial(hrtf, room, direction, sound, turn_deg, sign, rng)
    decided_at = None
    last = None
    for p in listen(pipe, audio, poses):
        last = p
        tr = p.tracked.get(sound)
        if decided_at is None and tr is not None and tr.decided and p.time_s > LEAD_S:
            decided_at = p.time_s - LEAD_S
    final = poses[-1][1]
    truth_head = final.T @ direction
    rec = {
        "azimuth_deg": round(float(vec_to_sph(direction)[0]), 2),
        "elevation_deg": round(float(vec_to_sph(direction)[1]), 2),
        "sound": sound, "turn_deg": float(turn_deg), "turn_sign": int(sign),
        "counted": bool(abs(truth_head[0]) >= math.sin(math.radians(FRONTAL_MARGIN_DEG))),
    }
    ahead = np.array([1.0, 0.0, 0.0])
    if turn_deg == 0.0:
        d = last.directions.get(sound) if last is not None else None
        est = d.vector if d is not None else ahead
        rec["static"] = _scores(est, direction, truth_head, est)
    tr = last.tracked.get(sound) if last is not None else None
    w = tr.world_vector if tr is not None else ahead
    rec["tracked"] = _scores(w, direction, truth_head, final.T @ w)
    rec["tracked"]["decided"] = bool(tr is not None and tr.decided)
    rec["tracked"]["decision_s"] = None if decided_at is None else round(decided_at, 4)
    return rec


def summarize(records: list[dict]) -> dict:
    """Per room and estimate/turn: ``front_back_confusion``, ``mean_azimuth_error_deg``,
    ``mean_error_deg``, ``n``; for the tracker also ``decided`` and ``median_decision_s``."""
    out: dict = {}
    for room in sorted({r["room"] for r in records}):
        rows = [r for r in records if r["room"] == room]
        res: dict = {}
        for key, sel in [("static", [r for r in rows if "static" in r])] + [
            (f"tracked_{t:g}", [r for r in rows if r["turn_deg"] == t]) for t in sorted({r["turn_deg"] for r in rows})
        ]:
            field = "static" if key == "static" else "tracked"
            if not sel:
                continue
            counted = [r[field]["confusion"] for r in sel if r["counted"]]
            s = {
                "n": len(sel),
                "front_back_confusion": round(float(np.mean(counted)), 4) if counted else None,
                "mean_azimuth_error_deg": round(float(np.mean([r[field]["azimuth_error_deg"] for r in sel])), 2),
                "mean_error_deg": round(float(np.mean([r[field]["error_deg"] for r in sel])), 2),
            }
            if field == "tracked":
                times = [r["tracked"]["decision_s"] for r in sel if r["tracked"]["decision_s"] is not None]
                s["decided"] = round(float(np.mean([r["tracked"]["decided"] for r in sel])), 4)
                s["median_decision_s"] = round(float(np.median(times)), 3) if times else None
            res[key] = s
        out[room] = res
    return out


def _trials(pipe, ears, rooms, dirs, names, turns, rng, records, progress) -> None:
    """Every trial of the experiment, in a fixed order (the seed's draws follow it)."""
    bar = progress_bar(total=len(rooms) * len(dirs) * len(names) * len(turns), desc="active", unit="trial",
                       disable=not progress)
    for room in rooms:
        pipe.set_noise_power(noise_floor(ears, rng=rng, room=room))
        for i, d in enumerate(dirs):
            for s in names:
                pipe.reset()
                pipe.clear_attention()
                pipe.attend(s)  # white noise is no class: all the bank's bins
                for t in turns:
                    rec = run_trial(pipe, ears, room, d, s, t, rng)
                    rec.update(room=room, direction=i)
                    records.append(rec)
                    bar.update()
    bar.close()


def run_active(*, out, hrtf="kemar", profile: str = "fast", rooms=ROOMS, n_horizontal: int = N_HORIZONTAL,
               n_off_plane: int = N_OFF_PLANE, sound_names=None, turns=TURNS_DEG, precedence: str | None = PRECEDENCE_DEFAULT,
               pairs: int = N_PAIRS, seed: int = 0, quick: bool = False, progress: bool = True) -> dict:
    """Run the experiment (module docstring); writes ``active.json``, ``trials.json``,
    ``pairs.json`` (with ``pairs`` > 0), ``active_confusion.png`` and ``REPORT.md`` into
    ``out`` and returns the summary. ``pairs``: two-source scenes per room of
    :data:`PAIR_ROOMS` (:func:`run_pair`), each heard with the head still and turning."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    for room in rooms:
        if room not in DISTANCE_M:
            raise ConfigError(f"unknown room {room!r} for eval active; valid: {', '.join(DISTANCE_M)}")
    turns = tuple(float(t) for t in turns)
    if 0.0 not in turns or any(not (0.0 <= t <= 90.0) for t in turns):
        raise ConfigError(f"turns must include 0 (the still head) and lie in 0..90 deg, got {turns}")
    names = tuple(sound_names) if sound_names is not None else ("white_noise",) + sounds.SOUND_CLASSES
    for s in names:
        if s not in sounds.available_sounds():
            raise ConfigError(f"unknown sound {s!r}; valid: {', '.join(sounds.available_sounds())}")
    if precedence not in PRECEDENCE:
        raise ConfigError(f"precedence must be one of {PRECEDENCE}, got {precedence!r}")
    for n, what in ((n_horizontal, "n_horizontal"), (n_off_plane, "n_off_plane")):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise ConfigError(f"{what} must be an integer >= 0, got {n!r}")
    if n_horizontal + n_off_plane == 0:
        raise ConfigError("no directions: give n_horizontal or n_off_plane > 0")
    if isinstance(pairs, bool) or not isinstance(pairs, (int, np.integer)) or pairs < 0:
        raise ConfigError(f"pairs must be an integer >= 0, got {pairs!r}")
    if quick:
        n_horizontal, n_off_plane = min(n_horizontal, 3), min(n_off_plane, 1)
        if sound_names is None:
            names = ("white_noise", "reverse_alarm")
        if tuple(turns) == TURNS_DEG:
            turns = (0.0, 30.0)
        pairs = min(pairs, 1)
    out = check_writable_folder(out, what="--out")
    ears = hrtf if isinstance(hrtf, HRTF) else HRTF.load(hrtf)
    grid = DirectionGrid.paper(ears)
    tracker = DirectionTracker(grid)
    pipe = AuditoryPipeline.load(ears, profile, precedence=precedence, tracker=tracker, progress=progress)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    dirs = draw_directions(rng, n_horizontal, n_off_plane)
    records = []
    t0 = time.perf_counter()
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # the networks are small: more threads busy-wait against the renderer's BLAS
    try:
        _trials(pipe, ears, rooms, dirs, names, turns, rng, records, progress)
        pair_records = run_pairs(pipe, ears, pairs, rng, progress)
    finally:
        torch.set_num_threads(threads)
    summary = {
        "rooms": summarize(records), "hrtf": ears.name, "profile": profile, "seed": int(seed), "quick": bool(quick),
        "directions": {"horizontal": int(n_horizontal), "off_plane": int(n_off_plane)}, "sounds": list(names),
        "turns_deg": list(turns), "turn_speed_deg_s": TURN_SPEED_DEG_S, "turn_start_s": TURN_START_S,
        "sound_s": SOUND_S, "distance_m": {r: DISTANCE_M[r] for r in rooms},
        "precedence": precedence,
        "tracker": {"outlier": tracker.outlier, "fold": tracker.fold, "decide_nats": tracker.decide_nats,
                    "weight": tracker.weight},
        "wall_s": round(time.perf_counter() - t0, 1),
        "targets": {"front_back_confusion_max": 0.05, "mean_azimuth_error_deg_max": 10.0, "turn_deg_max": 30.0},
    }
    if pair_records:
        summary["pairs"] = pairs_summary(pair_records, pairs)
    from acoustic_sim.experiments.report import write_json
    write_json(out / "trials.json", records)
    if pair_records:
        write_json(out / "pairs.json", pair_records)
    write_json(out / "active.json", summary)
    figure(summary, out / "active_confusion.png")
    (out / "REPORT.md").write_text(report(summary))
    return summary


def figure(summary: dict, path) -> None:
    """Front-back confusion rate against the turn angle per room, the still head's
    head-frame estimate as a dashed line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for i, (room, res) in enumerate(summary["rooms"].items()):
        turns = [t for t in summary["turns_deg"] if f"tracked_{t:g}" in res]
        rates = [res[f"tracked_{t:g}"]["front_back_confusion"] for t in turns]
        line, = ax.plot(turns, [np.nan if r is None else r for r in rates], "o-", label=f"{room}: tracked")
        if "static" in res and res["static"]["front_back_confusion"] is not None:
            ax.axhline(res["static"]["front_back_confusion"], ls="--", color=line.get_color(),
                       label=f"{room}: still head, head frame")
    ax.axhline(summary["targets"]["front_back_confusion_max"], color="k", lw=0.8, ls=":", label="target")
    ax.set_xlabel("head turn during the sound (deg)")
    ax.set_ylabel("front-back confusion rate")
    ax.set_ylim(0, max(0.6, ax.get_ylim()[1]))
    ax.legend(fontsize=8)
    ax.set_title(f"eval active: {summary['hrtf']}, {summary['profile']} models")
    fig.tight_layout()
    from acoustic_sim.files import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)


def table(summary: dict) -> str:
    """The summary as a Markdown table (REPORT.md and the README section)."""
    lines = ["| room | estimate | head turn (deg) | front-back confusion | mean azimuth error (deg) | "
             "mean error (deg) | decided | median time to decision (s) | trials |",
             "|---|---|---|---|---|---|---|---|---|"]
    for room, res in summary["rooms"].items():
        for key, s in res.items():
            est, turn = ("still head, head frame", "0") if key == "static" else ("tracked", key.split("_", 1)[1])
            fb = "-" if s["front_back_confusion"] is None else f"{s['front_back_confusion']:.3f}"
            dec = f"{s['decided']:.2f}" if "decided" in s else "-"
            md = "-" if s.get("median_decision_s") is None else f"{s['median_decision_s']:.2f}"
            lines.append(f"| {room} | {est} | {turn} | {fb} | {s['mean_azimuth_error_deg']:.1f} | "
                         f"{s['mean_error_deg']:.1f} | {dec} | {md} | {s['n']} |")
    return "\n".join(lines) + "\n"


def report(summary: dict) -> str:
    d = summary["directions"]
    return (
        "# eval active: head movement against front-back confusion\n\n"
        f"HRTF {summary['hrtf']}, {summary['profile']} models, seed {summary['seed']}"
        f"{' (quick: not the experiment numbers)' if summary['quick'] else ''}. "
        f"{d['horizontal']} directions on the horizontal plane and {d['off_plane']} off it per room, sounds: "
        f"{', '.join(summary['sounds'])}. The head turns once, {summary['turn_start_s']} s after the sound starts, "
        f"at {summary['turn_speed_deg_s']:g} deg/s; each sound lasts {summary['sound_s']} s. "
        f"Targets with a turn of at most {summary['targets']['turn_deg_max']:g} deg: front-back confusion at most "
        f"{summary['targets']['front_back_confusion_max']}, mean azimuth error at most "
        f"{summary['targets']['mean_azimuth_error_deg_max']:g} deg.\n\n"
        + table(summary)
        + ("\n" + pairs_table(summary) if summary.get("pairs") else "")
        + "\n![confusion rate against turn angle](active_confusion.png)\n\n"
        f"Made by `acoustic-sim eval active` in {summary['wall_s']} s.\n"
    )


BEGIN, END = "<!-- active:begin -->", "<!-- active:end -->"
"""The README's markers around the section :func:`update_readme` writes."""


def readme_section(results_dir, image_prefix: str = "results/active") -> str:
    """The README's section: the table and the figure of a finished run."""
    import json
    from pathlib import Path

    summary = json.loads((Path(results_dir) / "active.json").read_text())
    d = summary["directions"]
    flags = "".join([
        f" --horizontal {d['horizontal']}" if d["horizontal"] != N_HORIZONTAL else "",
        f" --off-plane {d['off_plane']}" if d["off_plane"] != N_OFF_PLANE else "",
        f" --seed {summary['seed']}" if summary["seed"] else "",
        f" --pairs {summary['pairs']['per_room'] if 'pairs' in summary else 0}"
        if summary.get("pairs", {}).get("per_room", 0) != N_PAIRS else "",
        " --quick" if summary["quick"] else "",
    ])
    return (
        f"{BEGIN}\nMade by `acoustic-sim eval active --out {image_prefix}{flags}` (HRTF {summary['hrtf']}, {summary['profile']} models, "
        f"{d['horizontal']} + {d['off_plane']} directions per room, {len(summary['sounds'])} sounds, evidence rule "
        f"`{summary['precedence']}`, seed {summary['seed']}; {summary['wall_s']} s).\n\n"
        + table(summary)
        + ("\n" + pairs_table(summary) if summary.get("pairs") else "")
        + f"\n![front-back confusion against the head turn]({image_prefix}/active_confusion.png)\n{END}"
    )


def update_readme(readme, results_dir, image_prefix: str = "results/active") -> bool:
    """Replace the README's active-hearing section; returns True when the file changed."""
    from acoustic_sim.experiments.report import replace_section

    return replace_section(readme, BEGIN, END, readme_section(results_dir, image_prefix))


__all__ = [  # with the names of active_scene and active_pairs, which this module's users import from here
    "BEGIN", "END", "DISTANCE_M", "FRONTAL_MARGIN_DEG", "LEAD_S", "LEVEL_DB_SPL", "N_HORIZONTAL", "N_OFF_PLANE", "N_PAIRS",
    "PAIRS", "PAIR_MIN_SEPARATION_DEG", "PAIR_ROOMS", "PAIR_TOLERANCE_DEG", "PAIR_TURN_DEG", "PRECEDENCE_DEFAULT",
    "ROOMS", "SOUND_S", "TURNS_DEG", "TURN_SPEED_DEG_S", "TURN_START_S", "WALL_CLEARANCE_M", "draw_directions",
    "draw_pair", "figure", "head_yaw_deg", "listen", "pairs_summary", "pairs_table", "readme_section",
    "render_scene", "render_trial", "report", "run_active", "run_pair", "run_pairs", "run_trial",
    "source_distance", "summarize", "summarize_pairs", "table", "update_readme",
]
