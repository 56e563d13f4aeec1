"""``eval active``'s two-source scenes: two sounds at once, heard with the head still and
turning (issue 33).

Each scene plays one pair of :data:`PAIRS` (classes of different spectra) from two
horizontal-plane directions at least :data:`PAIR_MIN_SEPARATION_DEG` apart, in the rooms of
:data:`PAIR_ROOMS`, with the scene of :mod:`~acoustic_sim.experiments.active_scene`. The
pipeline attends to both sounds; a scene counts when both are detected and each is
localized within :data:`PAIR_TOLERANCE_DEG` (:func:`run_pair`). ``pairs.json`` holds the
scenes, ``active.json``'s ``pairs`` their summary (:func:`pairs_summary`).
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.auditory.pipeline import AuditoryPipeline
from acoustic_sim.directions import angular_error_deg
from acoustic_sim.experiments.active_scene import listen, render_scene
from acoustic_sim.experiments.localization import noise_floor
from acoustic_sim.frames import sph_to_vec, vec_to_sph
from acoustic_sim.progress import progress_bar

N_PAIRS = 50
"""Two-source scenes per room (:func:`run_pair`)."""

PAIRS = (("reverse_alarm", "human_voice"), ("ratchet", "car_horn"), ("gearshift", "key_turning"))
"""Sound pairs played at once (issue 33): classes of different spectra."""

PAIR_ROOMS = ("anechoic", "car_cabin", "lab")
"""Rooms of the two-source measurement."""

PAIR_MIN_SEPARATION_DEG = 30.0
"""Least azimuth difference between the two sources of a pair (deg)."""

PAIR_TOLERANCE_DEG = 15.0
"""A source of a pair counts as localized within this angle (deg)."""

PAIR_TURN_DEG = 30.0
"""The head turn of the pairs' tracked condition (deg)."""


def draw_pair(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Two horizontal-plane directions at least :data:`PAIR_MIN_SEPARATION_DEG` apart."""
    a = rng.uniform(-180.0, 180.0)
    b = a + rng.uniform(PAIR_MIN_SEPARATION_DEG, 360.0 - PAIR_MIN_SEPARATION_DEG)
    return sph_to_vec(a, 0.0), sph_to_vec(((b + 180.0) % 360.0) - 180.0, 0.0)


def run_pair(pipe: AuditoryPipeline, hrtf: HRTF, room: str, pair, directions, turn_deg: float,
             rng: np.random.Generator) -> dict:
    """Both sounds of ``pair`` at once from ``directions``: per sound, whether the MelCNN
    detected it (its fused probability at the threshold in some frame) and the error of the
    pipeline's head-frame estimate (still head) or of the tracker's (``turn_deg`` > 0) at the
    end. ``pipe`` attends to both sounds."""
    sign = 1.0 if rng.random() < 0.5 else -1.0
    audio, poses = render_scene(hrtf, room, list(zip(pair, directions)), turn_deg, sign, rng)
    peak = dict.fromkeys(pair, 0.0)
    last = None
    for p in listen(pipe, audio, poses):
        last = p
        for name in pair:
            peak[name] = max(peak[name], p.probability(name))
    final = poses[-1][1]
    out = {"room": room, "pair": list(pair), "turn_deg": float(turn_deg),
           "azimuth_deg": [round(float(vec_to_sph(d)[0]), 2) for d in directions], "sources": []}
    for name, d in zip(pair, directions):
        if turn_deg == 0.0:
            e = last.directions.get(name)
            est = None if e is None else final @ e.vector
        else:
            e = last.tracked.get(name)
            est = None if e is None else e.world_vector
        err = None if est is None else round(float(angular_error_deg(est, d)), 2)
        out["sources"].append({"sound": name, "detected": bool(peak[name] >= pipe.settings.threshold), "error_deg": err})
    both = all(s["detected"] and s["error_deg"] is not None and s["error_deg"] <= PAIR_TOLERANCE_DEG
               for s in out["sources"])
    out["both"] = bool(both)
    return out


def summarize_pairs(records: list[dict]) -> dict:
    """Per room and condition (``static``, ``tracked_30``): the share of pairs with both
    sounds detected and localized within :data:`PAIR_TOLERANCE_DEG`, the share of sounds
    detected, and ``n``."""
    out: dict = {}
    for room in sorted({r["room"] for r in records}):
        out[room] = {}
        for turn in sorted({r["turn_deg"] for r in records}):
            sel = [r for r in records if r["room"] == room and r["turn_deg"] == turn]
            key = "static" if turn == 0.0 else f"tracked_{turn:g}"
            out[room][key] = {
                "n": len(sel),
                "both_localized": round(float(np.mean([r["both"] for r in sel])), 4),
                "detected": round(float(np.mean([s["detected"] for r in sel for s in r["sources"]])), 4),
            }
    return out


def run_pairs(pipe, ears, n, rng, progress) -> list[dict]:
    """The two-source scenes: ``n`` per room of :data:`PAIR_ROOMS`, the pairs of
    :data:`PAIRS` in turn, each with the head still and turning :data:`PAIR_TURN_DEG`."""
    records: list[dict] = []
    if n == 0:
        return records
    bar = progress_bar(total=len(PAIR_ROOMS) * n * 2, desc="pairs", unit="scene", disable=not progress)
    for room in PAIR_ROOMS:
        pipe.set_noise_power(noise_floor(ears, rng=rng, room=room))
        for i in range(n):
            pair = PAIRS[i % len(PAIRS)]
            directions = draw_pair(rng)
            pipe.reset()
            pipe.clear_attention()
            for name in pair:
                pipe.attend(name)
            for turn in (0.0, PAIR_TURN_DEG):
                records.append(run_pair(pipe, ears, room, pair, directions, turn, rng))
                bar.update()
    bar.close()
    return records


def pairs_summary(records: list[dict], per_room: int) -> dict:
    """``active.json``'s ``pairs``: :func:`summarize_pairs` of ``records`` with the
    measurement's settings and targets."""
    return {
        "rooms": summarize_pairs(records), "per_room": int(per_room), "sounds": [list(p) for p in PAIRS],
        "min_separation_deg": PAIR_MIN_SEPARATION_DEG, "tolerance_deg": PAIR_TOLERANCE_DEG,
        "targets": {"anechoic_min": 0.8, "rooms_min": 0.6},
    }


def pairs_table(summary: dict) -> str:
    """The two-source results as a Markdown table ('' without them)."""
    p = summary.get("pairs")
    if not p:
        return ""
    lines = [f"Two sounds at once ({', '.join(' + '.join(x) for x in p['sounds'])}; {p['per_room']} scenes per room, "
             f"at least {p['min_separation_deg']:g} deg apart): the share of scenes with both detected and each "
             f"localized within {p['tolerance_deg']:g} deg (targets: {p['targets']['anechoic_min']} anechoic, "
             f"{p['targets']['rooms_min']} in the rooms).\n",
             "| room | estimate | both localized | sounds detected | scenes |", "|---|---|---|---|---|"]
    for room, res in p["rooms"].items():
        for key, s in res.items():
            est = "still head, head frame" if key == "static" else f"tracked, {key.split('_', 1)[1]} deg turn"
            lines.append(f"| {room} | {est} | {s['both_localized']:.2f} | {s['detected']:.2f} | {s['n']} |")
    return "\n".join(lines) + "\n"
