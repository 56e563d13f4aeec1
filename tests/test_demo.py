"""``make demo``: one ReverseAlarm episode with the scripted policy (fast models), told in words,
with its figure, recording, sound and record; the narration's logic on made-up episodes."""

from __future__ import annotations

import json

import numpy as np
import pytest
import soundfile as sf
from PIL import Image

from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.cli import main
from apps.demo import Trace, narrate, run_demo, side_words
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE, SAMPLE_RATE
from acoustic_sim.viz.episode import outcome_words
from acoustic_sim.viz.play import check_recording


def test_demo_tells_what_happened_and_writes_its_files(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--seed", "1", "--profile", "fast"]) == 0
    out = capsys.readouterr().out
    doc = json.loads((tmp_path / "demo.json").read_text())
    record, moments = doc["record"], doc["moments"]
    assert doc["profile"] == "fast" and doc["seed"] == 1 and record["seed"] == 1
    # the figure: a real picture, not an empty canvas
    with Image.open(tmp_path / "demo.png") as im:
        assert im.width >= 800 and im.height >= 600
        pixels = np.asarray(im.convert("RGB"), dtype=np.float64)
    assert pixels.std() > 30 and len(np.unique(pixels.reshape(-1, 3), axis=0)) > 2000
    # the recording: one frame per step plus the reset
    assert check_recording(tmp_path / "demo.rrd")
    import rerun as rr

    frames = set()
    for chunk in rr.chunk.RrdReader(tmp_path / "demo.rrd").stream():
        if not chunk.is_static:
            frames.update(chunk.to_record_batch().column("frame").to_pylist())
    assert frames == set(range(record["steps"] + 1))
    # the sound: every step's block, both ears
    audio, fs = sf.read(tmp_path / "demo.wav", always_2d=True)
    assert fs == SAMPLE_RATE and audio.shape[1] == 2
    assert abs(audio.shape[0] - record["steps"] * SAMPLE_RATE / FRAME_RATE) <= 1 and np.abs(audio).max() > 0
    # the narration names the alarm's start, the recognition, the release and the outcome, at their times
    assert doc["narration"] == out.splitlines()[: len(doc["narration"])]
    if moments["alarm_start_s"] is not None:
        assert f"{moments['alarm_start_s']:5.2f} s  the lever enters R and the car's reverse alarm starts" in out
    else:
        assert "the car's reverse alarm never started" in out
    if moments["recognized_s"] is not None:
        assert (f"{moments['recognized_s']:5.2f} s  recognized as a reverse alarm" in out
                and f"from {moments['recognized_azimuth_deg']:+.0f} deg" in out)
    if moments["release_s"] is not None:
        assert f"{moments['release_s']:5.2f} s  the left hand lets go of the lever" in out
    else:
        assert "the left hand never let go" in out
    assert f": {outcome_words(record['outcome'])}" in out
    assert f"acoustic-sim play {tmp_path / 'demo.rrd'}" in out


def _trace(steps: int, *, alarm_from: float | None, beeper: tuple[float, float, float] | None = None) -> Trace:
    """A made-up episode: the alarm heard (p 0.9) from ``alarm_from`` deg from step 40 on, and
    optionally another vehicle's beeper heard from ``beeper[2]`` deg during steps beeper[0]..[1]."""
    k = SOUND_CLASSES.index("reverse_alarm")
    tr = Trace()
    tr.start_s = 0.5
    tr.labels = {"alarm": "reverse_alarm", "task/beeper": "reverse_alarm"}
    for n in range(steps + 1):
        prob, direction = np.zeros(6), np.zeros((6, 3))
        true = {}
        if alarm_from is not None and n >= 40:
            prob[k] = 0.9
            direction[k] = [np.cos(np.radians(alarm_from)), np.sin(np.radians(alarm_from)), 0.0]
            true["alarm"] = 0.0
        if beeper is not None and beeper[0] <= n <= beeper[1]:
            prob[k] = 0.8
            direction[k] = [np.cos(np.radians(beeper[2])), np.sin(np.radians(beeper[2])), 0.0]
            true["task/beeper"] = beeper[2]
        tr.t.append(n / FRAME_RATE)
        tr.prob.append(prob)
        tr.direction.append(direction)
        tr.confidence.append(np.where(prob > 0, 0.5, 0.0))
        tr.true_az.append(true)
    return tr


def _record(outcome: str, steps: int, onset_step: int | None, release_step: int | None) -> dict:
    onset = None if onset_step is None else 0.5 + onset_step / FRAME_RATE
    release = None if release_step is None else 0.5 + release_step / FRAME_RATE
    reaction = None if onset is None or release is None or release < onset else release - onset
    return {"outcome": outcome, "steps": steps, "episode_s": steps / FRAME_RATE, "target_onset_s": onset,
            "release_s": release, "reaction_s": reaction, "gear": "R"}


def _say(trace, record):
    return narrate(trace, record, threshold=0.5, lateral_range_deg=(5.0, 36.0), success_window_s=1.0, seed=3,
                   profile="fast")


REGION = "the alarm's region: lateral angle +5 to +36 deg from the turned head"


def test_narration_of_a_success_a_false_release_and_a_miss():
    text, m = _say(_trace(70, alarm_from=20.0), _record("success", 70, 38, 60))
    lines = text.splitlines()
    assert lines[1] == "   0.61 s  the lever enters R and the car's reverse alarm starts (truly +0 deg, in front)"
    assert lines[2] == ("   0.64 s  recognized as a reverse alarm (p = 0.90), 0.03 s after it started, from +20 deg "
                        f"azimuth, +0 deg elevation (in front; lateral +20 deg from the head, inside {REGION})")
    assert lines[3] == "   0.96 s  the left hand lets go of the lever (gear R), 0.35 s after the alarm started"
    assert lines[-1] == "  outcome at 1.12 s: success (reaction 0.35 s; a success lets go within 1.0 s)"
    assert m["recognized_s"] == pytest.approx(40 / FRAME_RATE) and m["accepted_s"] == m["recognized_s"]

    # fooled by another vehicle's beeper behind: let go before the car's alarm
    text, m = _say(_trace(30, alarm_from=None, beeper=(10, 30, 178.0)), _record("early", 30, None, 30))
    assert "   0.16 s  heard a reverse alarm from +178 deg (behind) until 0.48 s (it was another vehicle's beeper, " \
           "truly +178 deg, behind)" in text
    assert "the car's reverse alarm never started" in text
    assert "   0.48 s  the left hand lets go of the lever (gear R), before the car's alarm started" in text
    assert text.endswith(f"outcome at 0.48 s: {outcome_words('early')}")
    assert m["alarm_start_s"] is None and m["recognized_s"] is None

    # heard, but only from the side: never let go, pushed past R
    text, m = _say(_trace(90, alarm_from=-100.0), _record("past_reverse", 90, 38, None))
    assert f"from -100 deg azimuth, +0 deg elevation (on the right; lateral -80 deg from the head, outside {REGION})" in text
    assert "51 frames heard it with a direction: median -100 deg, 0 of them in the alarm's region" in text
    assert "the left hand never let go" in text and text.endswith("failure: pushed the lever past R")
    assert m["accepted_s"] is None and m["release_s"] is None


def test_narration_of_the_lever_waiting_for_quiet():
    """The policy's waits (``Trace.waiting``, filled from the policy by the demo's hook) are
    told as one line per run of waiting steps, with what it heard."""
    tr = _trace(70, alarm_from=20.0)
    tr.waiting = [(None, ())] * 71
    tr.waiting[5:12] = [("masked", ("human_voice",))] * 5 + [("masked", ("car_horn", "human_voice"))] * 2
    tr.waiting[12:20] = [("settling", ())] * 8
    tr.waiting[41:44] = [("listening", ())] * 3  # listening to the alarm is not a wait for quiet
    text, _ = _say(tr, _record("success", 70, 38, 60))
    lines = text.splitlines()
    assert lines[1] == ("   0.08 s  the lever waits for quiet (hearing car horn, human voice; after hearing a reverse "
                        "alarm) until 0.32 s")
    assert sum("waits for quiet" in line for line in lines) == 1
    assert lines[2].startswith("   0.61 s  the lever enters R")


def test_side_words():
    assert [side_words(a) for a in (0, 30, 90, 135, 180, -180, -90, -45, -140, 200)] == [
        "in front", "in front on the left", "on the left", "behind on the left", "behind", "behind", "on the right",
        "in front on the right", "behind on the right", "behind"]


def test_demo_errors(tmp_path):
    with pytest.raises(ConfigError, match="seed"):
        run_demo(out=tmp_path, seed=-1)
    with pytest.raises(ConfigError, match="profile"):
        run_demo(out=tmp_path, profile="huge")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ConfigError, match="is a file"):
        run_demo(out=tmp_path / "afile")
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", "--profile", "huge"])
    assert exit_info.value.code == 2
    assert main(["demo", "--seed", "-2", "--out", str(tmp_path / "d")]) == 2
    assert not (tmp_path / "d").exists()  # refused before anything was written


def test_narration_in_the_car_frame_at_the_mirror_image():
    # The head turned 22 deg right; the alarm heard at +158 deg from the head (+136 deg in the
    # car's frame, behind on the left): the front-back mirror image of +22 deg, the same
    # lateral angle, which the ears cannot tell from the dashboard speaker: accepted.
    tr = _trace(70, alarm_from=158.0)
    tr.neck = [np.array([np.radians(-22.0), 0.0])] * len(tr.t)
    text, m = narrate(tr, _record("success", 70, 38, 60), threshold=0.5, lateral_range_deg=(5.0, 36.0),
                      success_window_s=1.0, seed=3, profile="fast")
    assert f"from +136 deg azimuth, +0 deg elevation (behind on the left; lateral +22 deg from the head, inside {REGION})" in text
    assert "21 frames heard it with a direction: median +136 deg, 21 of them in the alarm's region" in text
    assert m["accepted_s"] == m["recognized_s"]
    # The policy's elevation bound: the same direction heard 40 deg up is outside.
    up = np.radians(40.0)
    for d in tr.direction:
        on = np.linalg.norm(d, axis=1) > 0
        d[on] *= np.cos(up)
        d[on, 2] = np.sin(up)
    text, m = narrate(tr, _record("past_reverse", 70, 38, None), threshold=0.5, lateral_range_deg=(5.0, 36.0),
                      success_window_s=1.0, seed=3, profile="fast", elevation_deg=(-90.0, 20.0))
    assert ("from +136 deg azimuth, +40 deg elevation (behind on the left; lateral +17 deg from the head, outside the "
            "alarm's region: lateral angle +5 to +36 deg from the turned head, elevation at most +20 deg)") in text
    assert "31 frames heard it with a direction: median +136 deg, 0 of them in the alarm's region" in text
    assert m["accepted_s"] is None
