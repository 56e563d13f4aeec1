"""acoustic_sim.files: atomic writes, up-front writability checks, reproducible WAVs."""

import numpy as np
import pytest
import soundfile as sf

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import atomic_path, check_writable, check_writable_folder, write_text, write_wav


def test_atomic_path_renames_into_place_only_on_success(tmp_path):
    target = tmp_path / "new" / "deeper" / "x.json"
    with pytest.raises(RuntimeError, match="midway"):
        with atomic_path(target) as tmp:
            assert tmp.parent == target.parent and tmp.suffix == ".json" and tmp.name.startswith(".")
            tmp.write_text("half")
            raise RuntimeError("midway")
    assert not target.exists() and not (tmp_path / "new").exists()  # nor the folders it made
    write_text(target, "whole\n")
    assert target.read_text() == "whole\n"
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise KeyboardInterrupt
    assert target.read_text() == "whole\n" and sorted(p.name for p in target.parent.iterdir()) == ["x.json"]


def test_unwritable_paths_are_one_line_config_errors(tmp_path):
    afile = tmp_path / "afile"
    afile.write_text("x")
    for path in (afile / "x.wav", afile / "sub" / "x.wav", "/proc/x.wav", "/proc/missing/x.wav"):
        with pytest.raises(ConfigError, match="cannot write --out"):
            check_writable(path, what="--out")
        with pytest.raises(ConfigError, match="cannot write"):
            write_text(path, "x")
    with pytest.raises(ConfigError, match="is a folder"):
        check_writable(tmp_path)
    with pytest.raises(ConfigError, match="is a file"):
        check_writable_folder(afile)
    assert check_writable(tmp_path / "a" / "b.wav") == tmp_path / "a" / "b.wav"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]  # the checks create nothing


def test_write_wav_is_float32_without_peak_chunk(tmp_path):
    audio = np.random.default_rng(0).standard_normal((2, 1000)) * 0.1
    a = write_wav(tmp_path / "a.wav", audio, 44100)
    b = write_wav(tmp_path / "b.wav", audio, 44100)
    assert a.read_bytes() == b.read_bytes() and b"PEAK" not in a.read_bytes()
    x, fs = sf.read(a, dtype="float32", always_2d=True)
    assert fs == 44100 and sf.info(a).subtype == "FLOAT" and np.array_equal(x.T, audio.astype(np.float32))
    bad = audio.copy()
    bad[0, 5] = np.nan
    with pytest.raises(ConfigError, match="NaN"):
        write_wav(tmp_path / "nan.wav", bad, 44100)
    with pytest.raises(ConfigError, match="shape"):
        write_wav(tmp_path / "mono.wav", audio[0], 44100)
    assert not (tmp_path / "nan.wav").exists() and not (tmp_path / "mono.wav").exists()
