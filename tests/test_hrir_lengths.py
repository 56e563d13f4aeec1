"""HRIRs of any length and sample rate load, render and measure (issue 32, item 2).

A 48 kHz file with short HRIRs used to end in a traceback in the renderer's reflection
responses (``fade[-taps // 4:]`` is ``(-taps) // 4``, one sample too many unless ``taps`` is
a multiple of 4), the same in ``measure_hrtf``'s gate (``taps`` not a multiple of 8), and
HRIRs longer than 1024 samples at 44.1 kHz stopped the late tail's 1024-point diffuse field.
"""

import numpy as np
import pytest
import sofar

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.hrtf_tables import hrtf_tables
from acoustic_sim.acoustics.measure import measure_hrtf
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.cli import main
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, sph_to_vec

LENGTHS = (8, 9, 31, 127, 255, 256, 1023, 4096)
RATES = (8000, 16000, 22050, 44100, 48000, 96000)
# Every length at 48 kHz and every rate at one odd length: not the full cross product, to
# stay fast (the longest response at the lowest rate has its own test below).
CASES = sorted({(48000, n) for n in LENGTHS} | {(fs, 31) for fs in RATES})

_AZ = np.array([0.0, 90.0, 180.0, 270.0, 45.0, 135.0, 225.0, 315.0])
_EL = np.array([0.0, 0.0, 0.0, 0.0, 30.0, -30.0, 30.0, -30.0])


def write_set(path, n_taps, fs):
    """A SimpleFreeFieldHRIR file of 8 directions: decaying noise, louder at the ear facing
    the source (receiver 0 = left, as sofar's default ReceiverPosition says)."""
    rng = np.random.default_rng(n_taps + fs)
    lateral = sph_to_vec(_AZ, _EL)[:, 1]  # y: toward the left ear
    decay = np.exp(-np.arange(n_taps) / max(n_taps / 4, 1.0))
    ir = rng.standard_normal((8, 2, n_taps)) * decay
    ir[:, 0] *= (1 + 0.8 * lateral)[:, None]
    ir[:, 1] *= (1 - 0.8 * lateral)[:, None]
    sofa = sofar.Sofa("SimpleFreeFieldHRIR")
    sofa.Data_IR = ir
    sofa.Data_SamplingRate = float(fs)
    sofa.SourcePosition = np.column_stack([_AZ, _EL, np.ones(8)])
    sofar.write_sofa(str(path), sofa)
    return path


@pytest.mark.parametrize(("fs", "n_taps"), CASES, ids=[f"{fs}Hz-{n}taps" for fs, n in CASES])
def test_any_hrir_length_and_rate_loads_renders_and_measures(tmp_path, fs, n_taps):
    hrtf = HRTF.load(write_set(tmp_path / "set.sofa", n_taps, fs))
    assert hrtf.sample_rate == SAMPLE_RATE and hrtf.n_directions == 8
    assert np.all(np.isfinite(hrtf.hrir))

    # A room with reflections (the short reflection responses), a late tail and background
    # noise (the diffuse field): every part of the renderer that reads the HRIRs.
    r = BinauralRenderer(hrtf, room_preset("lab"), rng=np.random.default_rng(0))
    noise = np.random.default_rng(1).standard_normal(SAMPLE_RATE // 10)
    r.add_source("s", noise, np.asarray(r.room.listener) + [0.0, 1.0, 0.0], level_db=70.0, start=0)
    y = r.render(0.05)
    n = round(0.05 * SAMPLE_RATE)
    assert y.shape == (2, n)
    assert np.all(np.isfinite(y)) and np.all(np.abs(y).max(axis=1) > 0)
    assert hrtf_tables(hrtf).diffuse_field()[0].shape == (2, 513)

    # The measurement's gate: an odd number of taps (not a multiple of 8) in its range.
    taps = min(max(n_taps, 64), 4096) | 1 if n_taps < 4096 else 4095
    out = tmp_path / "measured.sofa"
    info = measure_hrtf(hrtf=hrtf, room="anechoic", seconds=0.1, taps=taps, max_directions=2, out=out,
                        progress=False)
    measured = HRTF.load(out)
    assert info["taps"] == taps and measured.n_directions == 2
    assert np.all(np.isfinite(measured.hrir))


def test_hrirs_longer_than_the_renderer_streams_are_refused_up_front(tmp_path):
    """4096 taps at 8 kHz are 0.51 s, 22,580 taps at 44.1 kHz: more than the renderer's
    16,384-sample response window. It loads, and the renderer says so when built, not at the
    first block with a hint about the room."""
    hrtf = HRTF.load(write_set(tmp_path / "long.sofa", 4096, 8000))
    assert hrtf.n_taps >= 22580
    with pytest.raises(ConfigError, match=r"HRIRs of \d+ samples"):
        BinauralRenderer(hrtf, room_preset("anechoic"), rng=np.random.default_rng(0))


def test_cli_render_and_measure_a_short_48k_set(tmp_path, capsys):
    path = write_set(tmp_path / "short48k.sofa", 31, 48000)
    assert main(["render", "--hrtf", str(path), "--room", "lab", "--sound", "white_noise", "--seconds", "0.05",
                 "--azimuth", "90", "--out", str(tmp_path / "out.wav")]) == 0
    assert main(["measure-hrtf", "--hrtf", str(path), "--room", "anechoic", "--seconds", "0.1", "--taps", "100",
                 "--max-directions", "2", "--out", str(tmp_path / "m.sofa")]) == 0
    assert HRTF.load(tmp_path / "m.sofa").n_taps >= 100
    capsys.readouterr()
