"""Every acoustic-sim command, given bad arguments and bad files, ends the same way: exit
status 2, one line on stderr, no traceback, and no file left behind (README: "Bad arguments
and files end in a one-line error, never a traceback").

The commands run in-process through ``main``; a guard makes building a model, an env or a
benchmark fail the test at once, so every case must be refused before any expensive work
(which is also what a user wants: a typo should not cost minutes of training first).
"""

from __future__ import annotations

import subprocess
import sys
import types

import numpy as np
import pytest
import soundfile as sf

from acoustic_sim.cli import build_parser, main

PROC = "/proc/acoustic-sim-test"  # a folder where nothing can be created, even by root


class WouldBuild(AssertionError):
    """Raised by the guard: the command got past its input checks to expensive work."""


@pytest.fixture
def guard(monkeypatch):
    """Make every model, env, benchmark and experiment fail loudly if a case reaches it."""
    from apps import runner
    from acoustic_sim.auditory import melcnn, ssdenet
    from acoustic_sim.auditory.melcnn import fitting as melcnn_fitting
    from acoustic_sim.auditory.ssdenet import bank as ssdenet_training
    from acoustic_sim.experiments import hrtf_figures
    from apps import eval_tasks as tasks_experiment

    def stop(what):
        def raiser(*args, **kwargs):
            raise WouldBuild(f"{what} was reached: the bad input was not refused up front")

        return raiser

    monkeypatch.setattr(ssdenet.SSDENetBank, "load_or_train", classmethod(stop("SSDENetBank.load_or_train")))
    monkeypatch.setattr(melcnn.MelCNN, "load_or_train", classmethod(stop("MelCNN.load_or_train")))
    monkeypatch.setattr(ssdenet_training, "train_bank", stop("SSDENet training"))
    monkeypatch.setattr(melcnn, "train", stop("MelCNN training"))
    monkeypatch.setattr(melcnn_fitting, "train", stop("MelCNN training"))  # what load_or_train calls
    monkeypatch.setattr(runner, "make_env", stop("make_env"))
    monkeypatch.setattr(hrtf_figures, "pinna", stop("eval paper's experiments"))
    monkeypatch.setattr(tasks_experiment, "run_tasks", stop("eval tasks' episodes"))
    for name in ("bench_render", "bench_world", "bench_viz", "bench_env", "bench_pipeline"):
        monkeypatch.setitem(sys.modules, f"benchmarks.{name}", types.SimpleNamespace(run=stop(name)))


@pytest.fixture(scope="module")
def bad(tmp_path_factory):
    """Bad input files, in a folder of their own (``tmp_path`` is where outputs would go)."""
    d = tmp_path_factory.mktemp("bad-inputs")
    rng = np.random.default_rng(0)
    (d / "empty.wav").write_bytes(b"")
    (d / "text.wav").write_text("not a sound file\n")
    sf.write(d / "mono.wav", rng.standard_normal(4410).astype(np.float32) * 0.1, 44100, subtype="FLOAT")
    nan = rng.standard_normal((4410, 2)).astype(np.float32) * 0.1
    nan[1000, 0] = np.nan
    sf.write(d / "nan.wav", nan, 44100, subtype="FLOAT")
    sf.write(d / "silent.wav", np.zeros((4410, 2), np.float32), 44100, subtype="FLOAT")
    sf.write(d / "short.wav", np.zeros((100, 2), np.float32), 44100, subtype="FLOAT")
    loud = rng.standard_normal((4410, 2)).astype(np.float32) * 0.1
    loud[2000, 1] = 1e7
    sf.write(d / "loud.wav", loud, 44100, subtype="FLOAT")
    (d / "empty.sofa").write_bytes(b"")
    (d / "text.sofa").write_text("not a SOFA file\n")
    (d / "wav.sofa").write_bytes((d / "mono.wav").read_bytes())
    (d / "empty.rrd").write_bytes(b"")
    (d / "text.rrd").write_text("not a recording\n")
    (d / "garbage.pt").write_bytes(b"\x00not a checkpoint")
    (d / "folder.wav").mkdir()
    (d / "folder.json").mkdir()
    (d / "afile").write_text("a regular file, so nothing can be written under it\n")
    return d


# Each case: command words, then arguments; "{bad}" is the bad-files folder, "{out}" the
# (empty) folder where outputs go. Grouped by command so the counts say what is covered.
RENDER = [
    ("seed-negative", "--seed -1"),
    ("elevation-above-90", "--elevation 100"),
    ("elevation-below-90", "--elevation -90.5"),
    ("azimuth-nan", "--azimuth nan"),
    ("azimuth-not-a-number", "--azimuth left"),
    ("distance-negative", "--distance -1"),
    ("distance-outside-room", "--room car_cabin --distance 3"),
    ("seconds-zero", "--seconds 0"),
    ("level-absurd", "--level 500"),
    ("listener-two-numbers", "--listener 1,2"),
    ("room-unknown", "--room ballroom"),
    ("shoebox-without-rt60", "--room shoebox:4x3x2"),
    ("sound-unknown", "--sound trombone"),
    ("sound-missing-file", "--sound {bad}/missing.wav"),
    ("sound-empty-file", "--sound {bad}/empty.wav"),
    ("sound-not-audio", "--sound {bad}/text.wav"),
    ("sound-nan-samples", "--sound {bad}/nan.wav"),
    ("sound-silent", "--sound {bad}/silent.wav"),
    ("hrtf-missing-file", "--hrtf {bad}/missing.sofa"),
    ("hrtf-empty-file", "--hrtf {bad}/empty.sofa"),
    ("hrtf-not-sofa", "--hrtf {bad}/text.sofa"),
    ("hrtf-wav-as-sofa", "--hrtf {bad}/wav.sofa"),
    ("out-not-wav", "--out {out}/x.txt"),
    ("out-under-a-file", "--out {bad}/afile/x.wav"),
    ("out-in-proc", "--out /proc/x.wav"),
    ("out-in-proc-subfolder", f"--out {PROC}/x.wav"),
    ("out-is-a-folder", "--out {bad}/folder.wav"),
    ("option-unknown", "--colour red"),
]
MEASURE = [
    ("seed-negative", "--seed -1"),
    ("taps-too-few", "--taps 10"),
    ("max-directions-zero", "--max-directions 0"),
    ("distance-too-far", "--distance 10"),
    ("seconds-too-short", "--seconds 0.01"),
    ("room-unknown", "--room ballroom"),
    ("hrtf-missing-file", "--hrtf {bad}/missing.sofa"),
    ("hrtf-empty-file", "--hrtf {bad}/empty.sofa"),
    ("hrtf-not-sofa", "--hrtf {bad}/text.sofa"),
    ("out-not-sofa", "--out {out}/x.wav"),
    ("out-under-a-file", "--out {bad}/afile/x.sofa"),
    ("out-in-proc", f"--out {PROC}/x.sofa"),
]
BENCH_OUT = [
    ("out-under-a-file", "--out {bad}/afile/b.json"),
    ("out-in-proc", f"--out {PROC}/b.json"),
    ("out-is-a-folder", "--out {bad}/folder.json"),
]
DEMO = [
    ("seed-negative", "--seed -1"),
    ("profile-unknown", "--profile huge"),
    ("out-is-a-file", "--out {bad}/afile"),
    ("out-under-a-file", "--out {bad}/afile/runs"),
    ("out-in-proc", f"--out {PROC}/runs"),
]
TRAIN = [
    ("model-unknown", "resnet"),
    ("ssdenet-seed-negative", "ssdenet --seed -1"),
    ("ssdenet-hrtf-missing-file", "ssdenet --hrtf {bad}/missing.sofa"),
    ("ssdenet-hrtf-not-sofa", "ssdenet --hrtf {bad}/text.sofa"),
    ("ssdenet-out-under-a-file", "ssdenet --out {bad}/afile/x.pt"),
    ("ssdenet-out-in-proc", f"ssdenet --out {PROC}/x.pt"),
    ("melcnn-with-hrtf", "melcnn --hrtf spherical"),
    ("melcnn-out-under-a-file", "melcnn --out {bad}/afile/x.pt"),
    ("ssdenet-with-task", "ssdenet --task call-response"),
    ("policy-without-task", "policy --out {out}/p"),
    ("policy-without-out", "policy --task call-response"),
    ("policy-steps-zero", "policy --task call-response --steps 0 --out {out}/p"),
    ("policy-envs-zero", "policy --task call-response --envs 0 --out {out}/p"),
    ("policy-with-hrtf", "policy --task call-response --hrtf spherical --out {out}/p"),
    ("policy-out-under-a-file", "policy --task call-response --out {bad}/afile/p"),
]
WAV_IN = [
    ("wav-missing", "{bad}/missing.wav"),
    ("wav-a-folder", "{bad}"),
    ("wav-empty", "{bad}/empty.wav"),
    ("wav-not-audio", "{bad}/text.wav"),
    ("wav-mono", "{bad}/mono.wav"),
    ("wav-nan-samples", "{bad}/nan.wav"),
    ("wav-shorter-than-a-frame", "{bad}/short.wav"),
    ("wav-absurd-sample", "{bad}/loud.wav"),
]
LOCALIZE = WAV_IN + [
    ("method-unknown", "{bad}/silent.wav --method beamformer"),
    ("sound-unknown", "{bad}/silent.wav --sound trombone"),
    ("ssdenet-missing-file", "{bad}/silent.wav --ssdenet {bad}/missing.pt"),
    ("ssdenet-garbage-file", "{bad}/silent.wav --ssdenet {bad}/garbage.pt"),
    ("hrtf-missing-file", "{bad}/silent.wav --hrtf {bad}/missing.sofa"),
    ("fusion-unknown", "{bad}/silent.wav --fusion max"),
    ("sound-with-music", "{bad}/silent.wav --method music --sound ratchet"),
    ("fusion-with-gcc-phat", "{bad}/silent.wav --method gcc-phat --fusion sum"),
    ("ssdenet-checkpoint-with-music", "{bad}/silent.wav --method music --ssdenet {bad}/garbage.pt"),
]
DETECT = WAV_IN + [
    ("threshold-zero", "{bad}/silent.wav --threshold 0"),
    ("threshold-above-one", "{bad}/silent.wav --threshold 1.5"),
    ("threshold-nan", "{bad}/silent.wav --threshold nan"),
]
EVAL = [
    ("experiment-unknown", "figures"),
    ("paper-seed-negative", "paper --out {out}/p --seed -1"),
    ("paper-out-under-a-file", "paper --out {bad}/afile/p"),
    ("paper-out-in-proc", f"paper --out {PROC}/p"),
    ("paper-hrtf-missing-file", "paper --out {out}/p --hrtf {bad}/missing.sofa"),
    ("paper-hrtf-not-sofa", "paper --out {out}/p --hrtf {bad}/text.sofa"),
    ("active-seed-negative", "active --out {out}/a --seed -1"),
    ("active-out-under-a-file", "active --out {bad}/afile/a"),
    ("active-hrtf-missing-file", "active --out {out}/a --hrtf {bad}/missing.sofa"),
    ("active-directions-negative", "active --out {out}/a --horizontal -3"),
    ("active-sound-unknown", "active --out {out}/a --sound kazoo"),
    ("active-room-unknown", "active --out {out}/a --room moon"),
    ("tasks-episodes-zero", "tasks --out {out}/t --episodes 0"),
    ("tasks-seed-negative", "tasks --out {out}/t --seed -1"),
    ("tasks-out-under-a-file", "tasks --out {bad}/afile/t"),
    ("tasks-profile-unknown", "tasks --out {out}/t --profile huge"),
    ("readme-results-missing", "readme --results {bad}/missing --readme {bad}/afile"),
    ("readme-readme-missing", "readme --results {bad}/missing --readme {bad}/missing.md"),
]
SNAPSHOT = [
    ("scene-unknown", "--scene kitchen --out {out}/s.png"),
    ("width-zero", "--scene cabin --width 0 --out {out}/s.png"),
    ("height-too-large", "--scene cabin --height 5000 --out {out}/s.png"),
    ("width-not-a-number", "--scene cabin --width wide --out {out}/s.png"),
    ("out-not-png", "--scene cabin --out {out}/s.jpg"),
    ("out-under-a-file", "--scene cabin --out {bad}/afile/s.png"),
    ("out-in-proc", f"--scene cabin --out {PROC}/s.png"),
]
PLAY = [
    ("file-missing", "{bad}/missing.rrd"),
    ("file-empty", "{bad}/empty.rrd"),
    ("file-not-a-recording", "{bad}/text.rrd"),
    ("file-not-rrd", "{bad}/mono.wav"),
]
RUN = [
    ("task-unknown", "fetch --out {out}/r"),
    ("policy-unknown", "reverse-alarm --policy telepathic --out {out}/r"),
    ("policy-module-missing", "reverse-alarm --policy nowhere.module:Policy --out {out}/r"),
    ("episodes-zero", "reverse-alarm --episodes 0 --out {out}/r"),
    ("seed-negative", "reverse-alarm --seed -1 --out {out}/r"),
    ("no-camera-without-rrd", "reverse-alarm --no-camera --out {out}/r"),
    ("paper-car-other-task", "parking-brake --paper-car --out {out}/r"),
    ("paper-room-other-task", "reverse-alarm --paper-room --out {out}/r"),
    ("learned-policy-missing", "call-response --policy learned:{bad}/nothing --out {out}/r"),
    ("skill-mode-built-in-policy", "reverse-alarm --action-mode skill --out {out}/r"),
    ("out-under-a-file", "reverse-alarm --out {bad}/afile/r --rrd {out}/r.rrd"),
    ("out-in-proc", f"reverse-alarm --out {PROC}/r"),
    ("rrd-not-rrd", "reverse-alarm --out {out}/r --rrd {out}/r.txt"),
    ("rrd-under-a-file", "reverse-alarm --out {out}/r --rrd {bad}/afile/r.rrd"),
]
DEAF_SEARCH = [
    ("task-unknown", "fetch --out {out}/d"),
    ("episodes-zero", "reverse-alarm --episodes 0 --out {out}/d"),
    ("seed-held-out", "reverse-alarm --seed 3000 --episodes 2 --out {out}/d"),
    ("seeds-past-the-design-range", "reverse-alarm --seed 298 --episodes 5 --out {out}/d"),
    ("seed-negative", "reverse-alarm --seed -1 --out {out}/d"),
    ("out-under-a-file", "reverse-alarm --out {bad}/afile/d"),
    ("out-in-proc", f"reverse-alarm --out {PROC}/d"),
]

CASES = (
    [("render", f"--seconds 0.1 --out {{out}}/x.wav {a}" if "--out" not in a else f"--seconds 0.1 {a}", i)
     for i, a in RENDER]
    + [("measure-hrtf", f"--max-directions 2 --out {{out}}/m.sofa {a}" if "--out" not in a else f"--max-directions 2 {a}", i)
       for i, a in MEASURE]
    + [(f"bench {b}", a, i) for b in ("render", "world", "viz", "env", "pipeline") for i, a in BENCH_OUT]
    + [("demo", a if "--out" in a else f"--out {{out}}/runs {a}", i) for i, a in DEMO]
    + [("train", a, i) for i, a in TRAIN]
    + [("localize", f"--profile fast {a}", i) for i, a in LOCALIZE]
    + [("detect", f"--profile fast {a}", i) for i, a in DETECT]
    + [("eval", a, i) for i, a in EVAL]
    + [("snapshot", a, i) for i, a in SNAPSHOT]
    + [("play", a, i) for i, a in PLAY]
    + [("run", f"--profile fast {a}", i) for i, a in RUN]
    + [("deaf-search", a, i) for i, a in DEAF_SEARCH]
)


def _files(*folders) -> set:
    return {p for d in folders for p in d.rglob("*")}


@pytest.mark.parametrize("command, args, case", CASES, ids=[f"{c.replace(' ', '-')}:{i}" for c, _, i in CASES])
def test_bad_input_ends_in_one_line(command, args, case, bad, tmp_path, guard, capsys):
    out = tmp_path / "out"
    out.mkdir()
    argv = command.split() + args.format(bad=bad, out=out).split()
    before = _files(bad, out)
    try:
        code = main(argv)
    except SystemExit as exit_info:  # argparse's own errors
        code = exit_info.code
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert code == 2, (argv, captured.err)
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"acoustic-sim {command.split()[0]}"), lines[0]
    assert "error" in lines[0] and "Traceback" not in captured.err
    assert _files(bad, out) == before, "a file was left behind"
    assert not captured.out  # nothing printed as if it had worked


def test_every_command_is_covered():
    """The cases cover every subcommand of the parser (a new command needs bad-input cases)."""
    parser = build_parser()
    (sub,) = [a for a in parser._actions if a.dest == "command"]
    names = set()
    for name, p in sub.choices.items():
        nested = [a for a in p._actions if getattr(a, "choices", None) and a.dest in ("bench", "experiment")]
        names |= {f"{name} {n}" for n in nested[0].choices} if nested else {name}
    covered = {c for c, _, _ in CASES} | {f"eval {a.split()[0]}" for c, a, _ in CASES if c == "eval"}
    assert names <= covered, names - covered


@pytest.mark.parametrize(
    "args, message",
    [
        (["--seed", "-1"], "seed must be an integer >= 0"),
        (["--out", "/proc/x.wav"], "cannot write --out /proc/x.wav"),
    ],
)
def test_real_exit_status_and_stderr(tmp_path, args, message):
    """The two tracebacks of issue 32, as a user sees them: one line and status 2."""
    argv = ["render", "--seconds", "0.1", "--out", str(tmp_path / "x.wav"), *args]
    result = subprocess.run([sys.executable, "-m", "acoustic_sim.cli", *argv], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.stderr, result.stderr
    assert not list(tmp_path.iterdir())
