"""The acoustic-sim command: outputs, --help everywhere, one-line errors."""

import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf

from acoustic_sim.cli import build_parser, main


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "acoustic_sim.cli", *args], capture_output=True, text=True, timeout=300)


def test_every_subcommand_has_help(capsys):
    parser = build_parser()
    commands = [["render"], ["measure-hrtf"], ["bench"], ["bench", "render"], ["bench", "viz"], ["demo"], ["run"], ["play"]]
    for cmd in commands:
        with pytest.raises(SystemExit) as exit_info:
            main([*cmd, "--help"])
        assert exit_info.value.code == 0
        assert "usage: acoustic-sim" in capsys.readouterr().out
    assert parser.prog == "acoustic-sim"


def test_run_and_demo_help_explain_recordings_and_profiles(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--help"])
    assert exit_info.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--rrd FILE" in text and "--no-camera" in text
    assert "episode timeline" in text and "1 s after the previous one ended" in text  # how episodes share a file
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", "--help"])
    assert exit_info.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    for words in ("--profile {fast,paper}", "--seed SEED", "--out OUT", "demo.png", "demo.rrd", "fast (default"):
        assert words in text, words


def test_render_writes_a_two_channel_float_wav(tmp_path):
    out = tmp_path / "right.wav"
    code = main(["render", "--hrtf", "kemar", "--room", "car_cabin", "--sound", "white_noise", "--azimuth", "-90",
                 "--distance", "0.5", "--seconds", "0.3", "--seed", "3", "--out", str(out)])
    assert code == 0
    audio, fs = sf.read(out, dtype="float32", always_2d=True)
    info = sf.info(out)
    assert fs == 44100 and audio.shape == (13230, 2) and info.subtype == "FLOAT"
    assert np.all(np.isfinite(audio)) and np.abs(audio).max() < 1.0
    # Source on the right: the right channel is louder, though the cabin (critical distance
    # about 0.3 m) fills both ears with reverberation. Broadband: a pure tone (the alarm) in
    # the cabin can be louder at the far ear, where a room mode peaks (seen for 2 of 7 seeds).
    assert np.sum(audio[:, 1] ** 2) > 1.1 * np.sum(audio[:, 0] ** 2)
    again = tmp_path / "again.wav"
    main(["render", "--hrtf", "kemar", "--room", "car_cabin", "--sound", "white_noise", "--azimuth", "-90",
          "--distance", "0.5", "--seconds", "0.3", "--seed", "3", "--out", str(again)])
    # Same seed, same file, byte for byte (as --help promises): no PEAK chunk, whose time
    # stamp would differ between the two.
    assert again.read_bytes() == out.read_bytes()
    assert b"PEAK" not in out.read_bytes()


def test_render_impulse_is_the_brir(tmp_path):
    out = tmp_path / "brir.wav"
    assert main(["render", "--hrtf", "spherical", "--room", "anechoic", "--sound", "impulse", "--azimuth", "-90",
                 "--distance", "1", "--out", str(out)]) == 0
    h, fs = sf.read(out, always_2d=True)
    assert np.argmax(np.abs(h[:, 1])) < np.argmax(np.abs(h[:, 0]))  # right ear first
    assert np.sum(h[:, 1] ** 2) > np.sum(h[:, 0] ** 2)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--room", "ballroom"], "unknown room"),
        (["--room", "shoebox:4x3x2"], "needs --rt60"),
        (["--hrtf", "missing.sofa"], "missing.sofa"),
        (["--sound", "trombone"], "unknown sound"),
        (["--sound", "nothere.wav"], "nothere.wav"),
        (["--room", "car_cabin", "--distance", "3"], "not inside room"),
    ],
)
def test_bad_arguments_end_in_one_line(tmp_path, args, message):
    result = run_cli("render", "--seconds", "0.1", "--out", str(tmp_path / "x.wav"), *args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "Traceback" not in result.stderr
    assert not (tmp_path / "x.wav").exists()  # nothing half-written


def test_render_help_says_how_angles_are_read(capsys):
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "outside [-180, 180] wraps (190 is -170)" in text  # azimuth
    assert "-90..90 (default 0; outside that range is an error" in text  # elevation
    assert "same file byte for byte" in text


def test_render_azimuth_wraps(tmp_path):
    """--azimuth 190 is -170: the same file."""
    paths = [tmp_path / "a.wav", tmp_path / "b.wav"]
    for az, path in zip(("190", "-170"), paths):
        assert main(["render", "--hrtf", "spherical", "--sound", "impulse", "--azimuth", az, "--out", str(path)]) == 0
    a, b = (sf.read(p, dtype="float64")[0] for p in paths)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-6 * np.abs(b).max())  # the last bits of sin/cos may differ


def test_argparse_rejects_nonsense_numbers(tmp_path):
    result = run_cli("render", "--distance", "-1", "--out", str(tmp_path / "x.wav"))
    assert result.returncode == 2 and "positive" in result.stderr and "Traceback" not in result.stderr
