"""Active hearing: the pipeline's tracker in the loop, ``attend``, the evidence rules, and
``eval active`` end to end (quick)."""

import json

import numpy as np
import pytest

from acoustic_sim import cli
from acoustic_sim.auditory.pipeline import AuditoryPipeline
from acoustic_sim.auditory.tracker import DirectionTracker
from acoustic_sim.errors import ConfigError
from acoustic_sim.experiments import active
from acoustic_sim.frames import sph_to_vec


@pytest.fixture(scope="module")
def pipe(model_cache):
    p = AuditoryPipeline.load("kemar", "fast", precedence=active.PRECEDENCE_DEFAULT, tracker=True, progress=False)
    yield p


@pytest.mark.parametrize("azimuth", [150.0, -140.0])
def test_a_turning_head_places_a_source_behind_it_behind(pipe, azimuth):
    """Anechoic white noise from behind, the head turning 30 deg during it: the tracker's
    world direction is the source's (within 15 deg), not its mirror image in front."""
    pipe.reset()
    pipe.clear_attention()
    pipe.attend("white_noise")
    rng = np.random.default_rng(4)
    rec = active.run_trial(pipe, pipe.hrtf, "anechoic", sph_to_vec(azimuth, 0.0), "white_noise", 30.0, rng)
    assert rec["counted"] and not rec["tracked"]["confusion"]
    assert rec["tracked"]["error_deg"] < 15.0
    assert rec["tracked"]["decided"] and 0.0 < rec["tracked"]["decision_s"] < active.SOUND_S


def test_attend_and_the_tracker_fill_the_percept(pipe):
    pipe.reset()
    pipe.clear_attention()
    pipe.attend("white_noise")
    pipe.note_pose(0.0, np.eye(3))
    rng = np.random.default_rng(0)
    audio, _ = active.render_trial(pipe.hrtf, "anechoic", sph_to_vec(60.0, 0.0), "white_noise", 0.0, 1.0, rng)
    percepts = pipe.process(audio)
    last = percepts[-1]
    assert "white_noise" in last.directions and "white_noise" in last.tracked  # no class: attended
    assert abs(last.tracked["white_noise"].azimuth_deg - 60.0) < 15.0
    assert "tracked" in last.to_json()
    with pytest.raises(ConfigError, match="before the first block"):
        pipe.attend("car_horn")
    pipe.reset()
    with pytest.raises(ConfigError, match="is a class"):
        pipe.attend("car_horn", bins=[10, 20])
    with pytest.raises(ConfigError, match="bank's"):
        pipe.attend("low", bins=[0])
    with pytest.raises(ConfigError, match="indices"):
        pipe.attend("bad", bins=[5000])


def test_without_a_pose_the_head_frame_is_the_world_frame(pipe):
    pipe.reset()
    pipe.clear_attention()
    pipe.attend("white_noise")
    rng = np.random.default_rng(1)
    audio, _ = active.render_trial(pipe.hrtf, "anechoic", sph_to_vec(-70.0, 0.0), "white_noise", 0.0, 1.0, rng)
    last = pipe.process(audio)[-1]
    np.testing.assert_allclose(last.tracked["white_noise"].world_vector, last.tracked["white_noise"].head_vector)
    pipe.reset()
    AuditoryPipeline.load("kemar", "fast", progress=False).note_pose(0.0, np.eye(3))  # no tracker: ignored


def test_evidence_rules_and_their_arguments(model_cache):
    with pytest.raises(ConfigError, match="coherence"):
        AuditoryPipeline.load("kemar", "fast", precedence="coherence", coherence=1.5, progress=False)
    with pytest.raises(ConfigError, match="precedence"):
        AuditoryPipeline.load("kemar", "fast", precedence="echo", progress=False)
    rng = np.random.default_rng(2)
    p = AuditoryPipeline.load("kemar", "fast", precedence="wavefront+coherence", progress=False)
    audio, _ = active.render_trial(p.hrtf, "anechoic", sph_to_vec(-45.0, 0.0), "white_noise", 0.0, 1.0, rng)
    counts = {}
    for rule in ("wavefront", "wavefront+coherence", "coherence"):
        q = AuditoryPipeline.load("kemar", "fast", precedence=rule, progress=False)
        q.attend("white_noise")
        d = q.process(audio)[-1].directions.get("white_noise")
        counts[rule] = 0 if d is None else d.n_bins
    # A steady noise has one onset: the first wavefront alone leaves the last frames without
    # evidence, the coherent frames give it (an anechoic source is coherent in every bin).
    assert counts["wavefront"] == 0
    assert counts["coherence"] > 0 and counts["wavefront+coherence"] == counts["coherence"]


def test_pairs_are_apart_and_the_scene_holds_both():
    rng = np.random.default_rng(7)
    for _ in range(200):
        a, b = active.draw_pair(rng)
        assert float(np.degrees(np.arccos(np.clip(a @ b, -1, 1)))) >= active.PAIR_MIN_SEPARATION_DEG - 1e-9
        assert abs(a[2]) < 1e-12 and abs(b[2]) < 1e-12


def test_bad_experiment_arguments_are_refused_before_any_work(tmp_path):
    for kwargs, match in (({"rooms": ("moon",)}, "unknown room"), ({"turns": (10.0,)}, "turns"),
                          ({"sound_names": ("kazoo",)}, "unknown sound"), ({"precedence": "echo"}, "precedence"),
                          ({"n_horizontal": -1}, "n_horizontal"), ({"n_horizontal": 0, "n_off_plane": 0}, "no directions"),
                          ({"seed": -1}, "seed"), ({"pairs": -1}, "pairs")):
        with pytest.raises(ConfigError, match=match):
            active.run_active(out=tmp_path / "x", progress=False, **kwargs)
    assert not (tmp_path / "x").exists()


def test_eval_active_quick_writes_every_file(tmp_path, model_cache):
    out = tmp_path / "active"
    assert cli.main(["eval", "active", "--out", str(out), "--quick", "--room", "anechoic", "--room", "lab"]) == 0
    for name in ("active.json", "trials.json", "pairs.json", "REPORT.md", "active_confusion.png"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "active.json").read_text())
    assert set(summary["rooms"]) == {"anechoic", "lab"}
    assert set(summary["rooms"]["lab"]) == {"static", "tracked_0", "tracked_30"}
    trials = json.loads((out / "trials.json").read_text())
    assert len(trials) == 2 * 4 * 2 * 2  # rooms x directions x sounds x turns
    pairs = json.loads((out / "pairs.json").read_text())
    assert len(pairs) == len(active.PAIR_ROOMS) * 1 * 2  # rooms x scenes x (still, turning)
    assert set(summary["pairs"]["rooms"]) == set(active.PAIR_ROOMS)
    assert all(len(p["sources"]) == 2 for p in pairs)
    assert "Two sounds at once" in (out / "REPORT.md").read_text()
    # Anechoic, matched ears: the turn leaves no front-back confusion.
    assert summary["rooms"]["anechoic"]["tracked_30"]["front_back_confusion"] == 0.0
    readme = tmp_path / "README.md"
    readme.write_text(f"x\n{active.BEGIN}\n{active.END}\ny\n")
    assert active.update_readme(readme, out, image_prefix="results/active")
    text = readme.read_text()
    assert "results/active/active_confusion.png" in text and "| anechoic | tracked | 30 |" in text
    again = tmp_path / "again"
    active.run_active(out=again, quick=True, rooms=("anechoic",), pairs=0, progress=False)
    first = [t for t in trials if t["room"] == "anechoic"]
    assert json.loads((again / "trials.json").read_text()) == first  # same seed, same trials


def test_the_readme_section_is_the_committed_run():
    """The README's active-hearing table is what `eval readme` makes of results/active."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = (root / "README.md").read_text()
    section = text[text.index(active.BEGIN): text.index(active.END) + len(active.END)]
    assert section == active.readme_section(root / "results" / "active", image_prefix="results/active")
