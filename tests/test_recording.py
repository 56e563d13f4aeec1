"""localize and detect on files, block by block (acoustic_sim.auditory.recording; issue 32).

The streamed results must be those of the in-memory functions (which hold the whole
recording), memory must not depend on the file's length (checked by what is read and held,
not by timing or RSS), and music / gcc-phat must not build any learned model.
"""

from __future__ import annotations

import io
import json
import subprocess
import sys

import numpy as np
import pytest
import soundfile as sf
import torch
from scipy.signal import resample_poly

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory.features import MEL_FRAMES
from acoustic_sim.auditory.melcnn import MelCNN, NetConfig
from acoustic_sim.auditory.pipeline import AuditoryPipeline, detect_recording
from acoustic_sim.auditory.recording import (
    BLOCK_SAMPLES,
    CHUNK_FRAMES,
    BaselineTrack,
    DetectTrack,
    SSDENetTrack,
    StreamResampler,
    frame_chunks,
    wav_blocks,
)
from acoustic_sim.auditory.ssdenet import SSDENetBank
from acoustic_sim.cli import main
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.frames import SAMPLE_RATE, rotation_zyx, sph_to_vec

SECONDS = 24.0  # the "long" file: 1500 frames, 6 chunks, 17 read blocks
PREFIX = 5.0  # 312 frames: two chunks, so the state kept across a chunk boundary is exercised


def _render(kemar, azimuth: float, seconds: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    space = room_preset("anechoic")
    head = np.asarray(space.listener, float)
    r = BinauralRenderer(kemar, space, rng=rng)
    r.set_head_pose(head, rotation_zyx(0.0))
    r.add_source("s", sounds.white_noise(seconds, rng), head + 1.5 * sph_to_vec(azimuth, 0.0), level_db=80.0, start=0)
    return r.render(seconds)  # (2, n), full scale


@pytest.fixture(scope="module")
def long_wav(kemar, tmp_path_factory):
    """24 s: a 3 s noise render at azimuth 60 repeated, with 1 s of silence (no estimate)."""
    clip = _render(kemar, 60.0, 3.0)
    n = int(SECONDS * SAMPLE_RATE)
    audio = np.tile(clip, (1, int(np.ceil(n / clip.shape[1]))))[:, :n].astype(np.float32)
    audio[:, int(1.5 * SAMPLE_RATE) : int(2.5 * SAMPLE_RATE)] = 0.0
    d = tmp_path_factory.mktemp("long")
    path, prefix = d / "long.wav", d / "prefix.wav"
    sf.write(path, audio.T, SAMPLE_RATE, subtype="FLOAT")
    sf.write(prefix, audio[:, : int(PREFIX * SAMPLE_RATE)].T, SAMPLE_RATE, subtype="FLOAT")
    return path, prefix, audio[:, : int(PREFIX * SAMPLE_RATE)].astype(np.float64)


@pytest.fixture(scope="module")
def untrained(kemar):
    """A pipeline with untrained (seeded) models: agreement does not need good models, and
    these cost nothing to build."""
    grid = DirectionGrid.paper(kemar)
    bank = SSDENetBank(grid, np.arange(12, 560, 24), 16, hrtf_ident=kemar.ident, hrtf_name=kemar.name,
                       generator=torch.Generator().manual_seed(3))
    torch.manual_seed(4)
    cnn = MelCNN(NetConfig(conv1_channels=4, conv2_channels=4, hidden=16))
    cnn.characteristic_bins = {c: np.arange(40 + 10 * i, 300 + 10 * i) for i, c in enumerate(cnn.classes)}
    cnn.eval()
    return AuditoryPipeline(hrtf=kemar, grid=grid, ssdenet=bank, melcnn=cnn)


def _stream(track, path):
    rows = []
    for frames in frame_chunks(wav_blocks(path)):
        assert len(frames) <= CHUNK_FRAMES
        rows += list(zip(*track.push(frames))) if isinstance(track, DetectTrack) else track.push(frames)
    return rows, track


def _same_estimate(a, b, *, rtol=1e-5):
    """Two DirectionEstimates (or None) agree: the maps to float32 rounding, the direction
    wherever the map's top is not a near-tie (where rounding may pick either)."""
    assert (a is None) == (b is None)
    if a is None:
        return
    assert a.n_bins == b.n_bins and a.method == b.method
    np.testing.assert_allclose(a.existence, b.existence, rtol=rtol, atol=1e-6 * float(np.max(np.abs(b.existence), initial=1.0)))
    m = np.sort(np.asarray(b.existence, np.float64))
    if m.size == 0:  # GCC-PHAT: a continuous azimuth from the summed cross-spectrum
        assert (a.azimuth_deg, a.elevation_deg) == (pytest.approx(b.azimuth_deg, abs=1e-4), b.elevation_deg)
    elif m.size < 2 or m[-1] - m[-2] > 1e-4 * abs(m[-1]):
        assert (a.azimuth_deg, a.elevation_deg) == (b.azimuth_deg, b.elevation_deg)
    assert a.confidence == pytest.approx(b.confidence, abs=1e-5)


@pytest.mark.parametrize("method", ["ssdenet", "music", "gcc-phat"])
def test_localize_streamed_is_the_in_memory_result_on_a_prefix(untrained, kemar, long_wav, method):
    path, prefix, audio = long_wav
    ref_frames, ref_overall = untrained.localize(audio, method=method, window=MEL_FRAMES)

    def track():
        if method == "ssdenet":
            return SSDENetTrack(untrained, window=MEL_FRAMES)
        return BaselineTrack(method, kemar, untrained.grid, window=MEL_FRAMES)

    rows, whole = _stream(track(), path)
    assert whole.frames == len(rows) == 1500
    k = len(ref_frames)
    assert k == 312
    assert [t for t, _ in rows[:k]] == [t for t, _ in ref_frames]
    assert any(e is None for _, e in ref_frames) and any(e is not None for _, e in ref_frames)  # silence, then sound
    for (_, got), (_, want) in zip(rows[:k], ref_frames):
        if method == "ssdenet":
            _same_estimate(got, want)
        else:  # the same frames and the same arithmetic
            assert (got is None) == (want is None)
            if got is not None:
                assert (got.azimuth_deg, got.elevation_deg) == (want.azimuth_deg, want.elevation_deg)
                np.testing.assert_array_equal(got.existence, want.existence)
    _, short = _stream(track(), prefix)
    _same_estimate(short.overall(), ref_overall)
    if method != "ssdenet":  # the render is at azimuth 60 (left), and so is what the file gives
        assert 30.0 < whole.overall().azimuth_deg < 90.0


def test_localize_with_a_sound_class_streams_the_same(untrained, long_wav):
    path, prefix, audio = long_wav
    ref_frames, ref_overall = untrained.localize(audio, sound="ratchet")
    rows, _ = _stream(SSDENetTrack(untrained, sound="ratchet"), path)
    for (_, got), (_, want) in zip(rows[: len(ref_frames)], ref_frames):
        _same_estimate(got, want)
    _same_estimate(_stream(SSDENetTrack(untrained, sound="ratchet"), prefix)[1].overall(), ref_overall)


def test_detect_streamed_is_the_in_memory_result_on_a_prefix(untrained, long_wav):
    path, prefix, audio = long_wav
    times, probs, overall = detect_recording(untrained.melcnn, audio)
    rows, whole = _stream(DetectTrack(untrained.melcnn), path)
    k = len(times)
    assert whole.frames == 1500 and [t for t, _ in rows[:k]] == list(times)
    # The MelCNN runs on DETECT_BATCH frames at a time instead of 256: float32 rounding.
    np.testing.assert_allclose(np.stack([p for _, p in rows[:k]]), probs, rtol=0, atol=1e-6)
    np.testing.assert_allclose(_stream(DetectTrack(untrained.melcnn), prefix)[1].overall(), overall, rtol=0, atol=1e-6)


@pytest.mark.parametrize("rate, n, block", [(48000, 100_003, 7000), (22050, 30_001, 999), (96000, 50_000, 4096),
                                            (48000, 300, 65536)])
def test_stream_resampler_is_resample_poly_exactly(rate, n, block):
    x = np.random.default_rng(n).standard_normal((n, 2))
    g = np.gcd(rate, SAMPLE_RATE)
    want = resample_poly(x, SAMPLE_RATE // g, rate // g, axis=0)
    r = StreamResampler(rate, SAMPLE_RATE, n)
    got = np.concatenate([r.push(x[i : i + block]) for i in range(0, n, block)])
    np.testing.assert_array_equal(got, want)
    assert r._buffer.shape[0] <= r.h.size // r.up + 2 * r.down  # what it keeps: about the filter's span


def test_a_48khz_file_is_read_as_resample_poly_reads_it(tmp_path):
    x = (np.random.default_rng(1).standard_normal((3 * 48000 + 11, 2)) * 0.1).astype(np.float32)
    path = tmp_path / "x48.wav"
    sf.write(path, x, 48000, subtype="FLOAT")
    got = np.concatenate(list(wav_blocks(path, block=10_000)), axis=1)
    data, _ = sf.read(path, dtype="float64", always_2d=True)
    np.testing.assert_array_equal(got, resample_poly(data, 147, 160, axis=0).T)


@pytest.fixture
def reads(monkeypatch):
    """Every SoundFile.read call (``blocks`` reads through it too): the frames it asked for,
    and the lines written to ``reads.out`` before it (a test makes it stdout: pytest's capture
    resets sys.stdout after the fixtures are set up)."""
    asked = []
    original = sf.SoundFile.read
    out = io.StringIO()

    def spy(self, frames=-1, *args, **kwargs):
        asked.append((frames, out.getvalue().count("\n")))
        return original(self, frames, *args, **kwargs)

    monkeypatch.setattr(sf.SoundFile, "read", spy)
    spy.asked, spy.out = asked, out
    return spy


@pytest.mark.parametrize("command", ["localize --method music", "localize --method gcc-phat", "localize", "detect"])
def test_memory_is_bounded_by_the_block_not_the_file(command, untrained, long_wav, reads, monkeypatch):
    """The file is never read whole: every read asks for at most a block, the tracks get at
    most a chunk of frames and keep at most a window of them, and rows are written while the
    file is still being read."""
    from acoustic_sim import cli_auditory

    monkeypatch.setattr(sys, "stdout", reads.out)
    monkeypatch.setattr(cli_auditory, "_pipeline", lambda *a, **k: untrained)
    monkeypatch.setattr(MelCNN, "load_or_train", classmethod(lambda cls, *a, **k: untrained.melcnn))
    held = []
    for cls in (SSDENetTrack, BaselineTrack, DetectTrack):
        def watched(self, frames, _push=cls.push):
            assert len(frames) <= CHUNK_FRAMES
            result = _push(self, frames)
            held.append(max(getattr(self, name).shape[0] for name in ("_maps", "_tail", "_mel", "_vol")
                            if hasattr(self, name)))
            return result

        monkeypatch.setattr(cls, "push", watched)
    assert main(command.split() + [str(long_wav[0]), "--profile", "fast"]) == 0
    rows = [json.loads(line) for line in reads.out.getvalue().splitlines()]
    assert len(rows) == 1501 and rows[-1]["overall"] is True and rows[-1].get("frames", 1500) == 1500
    assert 0 < max(held) <= MEL_FRAMES - 1  # frames kept between chunks: a window, not the file
    asked = [frames for frames, _ in reads.asked]
    assert len(asked) >= 2 * (int(SECONDS * SAMPLE_RATE) // BLOCK_SAMPLES)  # the check's scan, then the pass
    assert all(0 < f <= BLOCK_SAMPLES for f in asked), sorted(set(asked))
    assert reads.asked[-1][1] >= 1000  # most rows were out before the last read


def test_every_read_asks_for_at_most_a_block(long_wav, reads, kemar):
    track = BaselineTrack("gcc-phat", kemar, DirectionGrid.paper(kemar))
    for frames in frame_chunks(wav_blocks(long_wav[0])):
        track.push(frames)
    assert track.frames == 1500
    asked = [frames for frames, _ in reads.asked]
    assert len(asked) >= int(SECONDS * SAMPLE_RATE) // BLOCK_SAMPLES
    assert all(0 < f <= BLOCK_SAMPLES for f in asked), sorted(set(asked))


@pytest.fixture
def no_models(monkeypatch, tmp_path):
    """An empty model cache, and every way to load or train SSDENet or MelCNN raises."""
    from acoustic_sim.auditory import melcnn, ssdenet
    from acoustic_sim.auditory.melcnn import fitting as melcnn_fitting
    from acoustic_sim.auditory.ssdenet import bank as ssdenet_training

    cache = tmp_path / "cache"
    cache.mkdir()
    monkeypatch.setenv("ACOUSTIC_SIM_CACHE", str(cache))

    def stop(what):
        def raiser(*args, **kwargs):
            raise AssertionError(f"{what} was called")

        return raiser

    for name in ("load_or_train", "load", "rebuild"):
        monkeypatch.setattr(ssdenet.SSDENetBank, name, classmethod(stop(f"SSDENetBank.{name}")))
    for name in ("load_or_train", "load"):
        monkeypatch.setattr(melcnn.MelCNN, name, classmethod(stop(f"MelCNN.{name}")))
    monkeypatch.setattr(ssdenet_training, "train_bank", stop("SSDENet training"))
    monkeypatch.setattr(melcnn, "train", stop("MelCNN training"))
    monkeypatch.setattr(melcnn_fitting, "train", stop("MelCNN training"))  # what load_or_train calls
    monkeypatch.setattr(ssdenet.SSDENetBank, "__init__", stop("SSDENetBank()"))
    monkeypatch.setattr(melcnn.MelCNN, "__init__", stop("MelCNN()"))
    return cache


@pytest.fixture(scope="module")
def left_wav(kemar, tmp_path_factory):
    path = tmp_path_factory.mktemp("left") / "left.wav"
    sf.write(path, _render(kemar, 60.0, 1.0, seed=5).T.astype(np.float32), SAMPLE_RATE, subtype="FLOAT")
    return path


@pytest.mark.parametrize("method", ["music", "gcc-phat"])
def test_baseline_methods_build_no_learned_model(method, left_wav, no_models, capsys):
    assert main(["localize", str(left_wav), "--method", method]) == 0  # default --profile paper: never trained
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    last = rows[-1]
    assert last["overall"] is True and last["method"] == method and "fusion" not in last
    assert 30.0 < last["azimuth_deg"] < 90.0, last  # the render is at azimuth 60
    assert all(r["azimuth_deg"] is not None for r in rows[30:-1])
    assert not list(no_models.iterdir())  # nothing was written to the cache


def test_baseline_methods_do_not_even_import_torch(left_wav, tmp_path):
    code = ("import sys; from acoustic_sim.cli import main; "
            f"rc = main(['localize', {str(left_wav)!r}, '--method', 'music']); "
            "assert rc == 0; assert 'torch' not in sys.modules, 'torch was imported'")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                       env={**__import__("os").environ, "ACOUSTIC_SIM_CACHE": str(tmp_path)})
    assert r.returncode == 0, r.stderr[-2000:]
    assert json.loads(r.stdout.splitlines()[-1])["method"] == "music"


@pytest.mark.parametrize("flag", [["--sound", "ratchet"], ["--fusion", "sum"], ["--ssdenet", "x.pt"]])
def test_ssdenet_options_with_a_baseline_are_refused(flag, left_wav, no_models, capsys):
    assert main(["localize", str(left_wav), "--method", "music", *flag]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{flag[0]} applies to --method ssdenet only" in err[0]
