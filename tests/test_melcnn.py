"""MelCNN: fusion, loss, characteristic bins, the sound-data generator, training and checkpoints."""

import numpy as np
import pytest
import torch

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory import checkpoint
from acoustic_sim.auditory import melcnn as mc
from acoustic_sim.auditory import sound_data as sd
from acoustic_sim.auditory.features import normalize_log_mel
from acoustic_sim.auditory.frontend import bin_frequencies
from acoustic_sim.errors import ConfigError


@pytest.fixture(scope="module")
def fast_cache(model_cache):
    """The test session's model cache (tests/conftest.py), where the fast models are trained
    once through the cache on first use; training them again here would double the suite's
    longest part."""
    return model_cache


@pytest.fixture(scope="module")
def fast_model(fast_cache):
    """The ``fast`` profile, from the session's cache (trained there on first use)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(checkpoint.CACHE_ENV, str(fast_cache))
        return mc.MelCNN.load_or_train("fast", progress=False)


@pytest.fixture(scope="module")
def anechoic_bank():
    """One anechoic BRIR (frontal, 1 m): enough for fast data-generator tests."""
    room = room_preset("anechoic")
    renderer = BinauralRenderer(HRTF.load("kemar"), room, rng=np.random.default_rng(0))
    return sd.BRIRBank({"anechoic": [renderer.impulse_response(np.array([1.0, 0.0, 0.0]))]})


# -- fusion --------------------------------------------------------------------------------


def test_fusion_weights_by_ear_volume():
    pl, pr = np.array([0.2, 0.8, 1.0]), np.array([0.6, 0.4, 0.0])
    # V_l = 3 V_r: (3 * 0.2 + 0.6) / 4 = 0.3, (3 * 0.8 + 0.4) / 4 = 0.7, 3 / 4 = 0.75.
    np.testing.assert_allclose(mc.fuse(pl, pr, 3.0, 1.0), [0.3, 0.7, 0.75])
    np.testing.assert_allclose(mc.fuse(pl, pr, 2.5, 2.5), [0.4, 0.6, 0.5])  # equal: the mean
    np.testing.assert_allclose(mc.fuse(pl, pr, 1e-9, 0.0), pl)  # one silent ear: the other one
    np.testing.assert_allclose(mc.fuse(pl, pr, 0.0, 0.0), [0.4, 0.6, 0.5])  # silence: the mean
    batch = mc.fuse(np.stack([pl, pl]), np.stack([pr, pr]), np.array([3.0, 0.0]), np.array([1.0, 0.0]))
    np.testing.assert_allclose(batch, [[0.3, 0.7, 0.75], [0.4, 0.6, 0.5]])


def test_one_frame_fusion_is_the_batch_fusion_bit_for_bit():
    rng = np.random.default_rng(3)
    p = rng.uniform(size=(5, 2, 6))
    v = rng.exponential(size=(5, 2))
    v[2] = 0.0  # a silent frame
    batch = mc.fuse(p[:, 0], p[:, 1], v[:, 0], v[:, 1])
    for k in range(5):
        assert np.array_equal(mc.fuse_unchecked(p[k, 0], p[k, 1], v[k, 0], v[k, 1]), batch[k])


def test_forward_pools_like_torchs_nchw_max_pool_bit_for_bit():
    torch.manual_seed(0)
    model = mc.MelCNN(mc.get_profile("fast").net).eval()
    x = torch.rand(6, 25, 128) * -1.0
    with torch.inference_mode():
        y = x.unsqueeze(1).transpose(2, 3).contiguous()
        y = model.pool1(torch.relu(model.conv1(y)))  # plain NCHW pooling
        y = model.pool2(torch.relu(model.conv2(y)))
        y = torch.relu(model.fc2(torch.relu(model.fc1(y.flatten(1)))))
        assert torch.equal(model(x), model.out(y))


@pytest.mark.parametrize("args", [
    ([0.2], [0.3, 0.4], 1.0, 1.0),  # shapes differ
    ([0.2], [0.3], -1.0, 1.0),  # negative volume
    ([0.2], [0.3], np.nan, 1.0),  # NaN volume
    ([1.2], [0.3], 1.0, 1.0),  # not a probability
    ([np.nan], [0.3], 1.0, 1.0),
    ([[0.2], [0.1]], [[0.3], [0.3]], 1.0, 1.0),  # volumes miss the batch axis
])
def test_fusion_rejects_bad_input(args):
    with pytest.raises(ConfigError):
        mc.fuse(*args)


# -- loss ----------------------------------------------------------------------------------


def test_kl_loss_is_bce_minus_label_entropy():
    torch.manual_seed(0)
    logits = torch.randn(5, 6)
    hard = (torch.rand(5, 6) > 0.5).float()
    bce = torch.nn.functional.binary_cross_entropy_with_logits(logits, hard, reduction="sum") / 5
    torch.testing.assert_close(mc.kl_divergence_loss(logits, hard), bce)
    soft = torch.rand(5, 6)
    assert float(mc.kl_divergence_loss(torch.logit(soft), soft)) == pytest.approx(0.0, abs=1e-5)
    assert float(mc.kl_divergence_loss(logits, soft)) > 0.0
    with pytest.raises(ConfigError):
        mc.kl_divergence_loss(logits, soft[:, :5])


# -- characteristic bins -------------------------------------------------------------------


def test_characteristic_bins_smallest_set_holding_the_energy():
    s = np.zeros((6, 10))
    s[:, :] = 0.01
    s[0, [2, 5, 7]] = [5.0, 3.0, 1.5]  # 9.5 of 9.57: 90 % needs all three
    frames = np.full(6, 2)
    bins = mc.characteristic_bins(s, frames, energy_fraction=0.9)
    np.testing.assert_array_equal(bins["car_horn"], [2, 5, 7])
    assert bins["car_horn"].dtype == np.int64
    assert mc.characteristic_bins(s, frames, energy_fraction=0.5)["car_horn"].tolist() == [2]
    assert bins["ratchet"].size == 9  # flat spectrum: 90 % of 10 equal bins
    frames[3] = 0
    with pytest.raises(ConfigError, match="gearshift"):
        mc.characteristic_bins(s, frames)


def test_characteristic_bins_of_the_reverse_alarm_hold_its_beep(fast_model):
    bins = fast_model.characteristic_bins
    assert set(bins) == set(sd.CLASSES)
    freqs = bin_frequencies()[bins["reverse_alarm"]]
    # The beeper's fundamental is 1000-1300 Hz: it must be in the set, and the set must be
    # the beep's harmonics (within one bin), not the broadband classes' low or high bins.
    assert np.any((freqs >= 1000) & (freqs <= 1300))
    harmonic = np.min(np.abs(freqs[:, None] / np.arange(1, 6)[None, :] - 1150.0) - 150.0 - 22.0
                      / np.arange(1, 6)[None, :], axis=1) <= 0
    assert harmonic.mean() >= 0.9, freqs
    assert fast_model.characteristic_bins["key_turning"].size > bins["reverse_alarm"].size


# -- the data generator --------------------------------------------------------------------


def test_same_seed_same_examples(anechoic_bank):
    cfg = sd.SoundDataConfig(rooms=("anechoic",), scene_seconds=1.0, start_seconds=(-0.5, 0.7), first_window_frame=25)
    a = sd.generate_examples(12, np.random.default_rng(5), config=cfg, bank=anechoic_bank)
    b = sd.generate_examples(12, np.random.default_rng(5), config=cfg, bank=anechoic_bank)
    c = sd.generate_examples(12, np.random.default_rng(6), config=cfg, bank=anechoic_bank)
    for name in ("patches", "targets", "labels", "volumes", "room", "spectrum_sum", "spectrum_frames"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert not np.array_equal(a.patches, c.patches)
    assert a.patches.shape == (12, 2, 25, 128) and a.patches.dtype == np.float32
    assert a.targets.shape == (12, 2, 6) and a.labels.shape == (12, 6) and a.volumes.shape == (12, 2)
    assert np.all((a.patches >= -1) & (a.patches <= 0)) and np.all(a.volumes > 0)


def test_brir_bank_is_seeded():
    a = sd.BRIRBank.build(np.random.default_rng(3), rooms=("anechoic",), per_room=2)
    b = sd.BRIRBank.build(np.random.default_rng(3), rooms=("anechoic",), per_room=2)
    assert len(a.brirs["anechoic"]) == 2
    for x, y in zip(a.brirs["anechoic"], b.brirs["anechoic"]):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a.brirs["anechoic"][0], a.brirs["anechoic"][1])


def test_labels_follow_the_energy_in_the_window(anechoic_bank):
    # One class, anechoic, starting at 1.5 s and lasting 0.5 s at 20 dB SNR: windows that end
    # before the onset, or that start well after the sound (no reverberation here), are empty;
    # windows inside the sound carry its label.
    cfg = sd.SoundDataConfig(rooms=("anechoic",), class_count_probs=(0.0, 1.0), sound_seconds=(0.5, 0.5),
                             start_seconds=(1.5, 1.5), snr_db=(20.0, 20.0), scene_seconds=3.0,
                             first_window_frame=25, window_hop_frames=1)
    rng = np.random.default_rng(11)
    for _ in range(3):
        ex = sd.scene_examples(cfg, anechoic_bank, rng)
        end_s = (np.arange(25, 25 + len(ex)) * 705.6) / 44100  # end time of each window
        start_s = end_s - (24 * 705.6 + 2048) / 44100
        assert not ex.labels[end_s < 1.49].any()
        assert not ex.labels[start_s > 2.05].any()
        present = ex.labels.any(axis=0)
        assert present.sum() == 1  # the one class, and it is heard in some window
        c = int(np.flatnonzero(present)[0])
        assert ex.labels[(end_s > 1.65) & (start_s < 1.9), c].mean() > 0.5


def test_data_config_and_arguments_are_checked(anechoic_bank):
    with pytest.raises(ConfigError, match="class_count_probs"):
        sd.SoundDataConfig(class_count_probs=(0.5, 0.6))
    with pytest.raises(ConfigError, match="snr_db"):
        sd.SoundDataConfig(snr_db=(10.0, -10.0))
    with pytest.raises(ConfigError, match="rooms"):
        sd.SoundDataConfig(rooms=("bathroom",))
    with pytest.raises(ConfigError, match="n_examples"):
        sd.generate_examples(0, np.random.default_rng(0), bank=anechoic_bank)
    with pytest.raises(ConfigError, match="rng"):
        sd.generate_examples(3, 42, bank=anechoic_bank)
    with pytest.raises(ConfigError, match="car_cabin"):
        sd.scene_examples(sd.SoundDataConfig(rooms=("car_cabin",)), anechoic_bank, np.random.default_rng(0))


# -- training, evaluation, checkpoints -----------------------------------------------------


def test_fast_model_beats_chance_on_heldout_data(fast_model):
    result = mc.evaluate(fast_model, mc.heldout_rng("fast"), mc.PROFILES["fast"].eval_examples, brirs_per_room=1)
    assert set(result) >= {"f1_macro", "per_class", "threshold"} and result["threshold"] == 0.5
    assert set(result["per_class"]) == set(sd.CLASSES)
    for scores in result["per_class"].values():
        assert set(scores) >= {"precision", "recall", "f1"}
    # Chance: the best trivial detector says "present" always, F1 = 2q / (1 + q) for a
    # class of prevalence q (about 0.3 here). The fast model must beat it by 0.2 at least.
    q = np.array([s["support"] for s in result["per_class"].values()]) / result["n_examples"]
    chance = float(np.mean(2 * q / (1 + q)))
    assert result["f1_macro"] >= chance + 0.2, (result, chance)


def test_inference_on_silence_is_finite(fast_model):
    silent = normalize_log_mel(np.zeros((2, 25, 128)))
    p = fast_model.predict(silent)
    assert p.shape == (2, 6) and np.all(np.isfinite(p)) and np.all((p >= 0) & (p <= 1))
    fused = fast_model.detect(silent, np.zeros(2))
    np.testing.assert_allclose(fused, p.mean(axis=0), rtol=1e-6)
    assert fast_model.detect(np.stack([silent] * 3), np.zeros((3, 2))).shape == (3, 6)
    with pytest.raises(ConfigError):
        fast_model.predict(np.zeros((25, 128)))
    with pytest.raises(ConfigError):
        fast_model.predict(np.full((2, 25, 128), np.nan))
    with pytest.raises(ConfigError):
        fast_model.detect(silent, np.zeros(3))


def test_checkpoint_round_trip_and_cache(fast_model, fast_cache, tmp_path, monkeypatch):
    path = fast_model.save(tmp_path / "m.pt")
    loaded = mc.MelCNN.load(path)
    x = np.random.default_rng(0).uniform(-1, 0, (4, 2, 25, 128)).astype(np.float32)
    np.testing.assert_array_equal(loaded.predict(x), fast_model.predict(x))
    assert loaded.classes == fast_model.classes == sd.CLASSES
    for name, bins in fast_model.characteristic_bins.items():
        np.testing.assert_array_equal(loaded.characteristic_bins[name], bins)
    meta = checkpoint.read_metadata(path)
    assert meta["kind"] == "melcnn" and meta["profile"] == "fast" and meta["sample_rate"] == 44100
    assert meta["characteristic_bins"]["reverse_alarm"] == fast_model.characteristic_bins["reverse_alarm"].tolist()
    # The fixture trained through the cache: the next load_or_train reads that file.
    monkeypatch.setenv(checkpoint.CACHE_ENV, str(fast_cache))
    cached = mc.MelCNN.cache_path("fast")
    assert cached.parent == fast_cache and cached.exists()
    np.testing.assert_array_equal(mc.MelCNN.load_or_train("fast", progress=False).predict(x), fast_model.predict(x))


def test_cache_name_follows_the_recipe_and_a_voice_engine_change_warns(fast_model, fast_cache, monkeypatch):
    import dataclasses

    from acoustic_sim.acoustics import sounds

    fast = mc.PROFILES["fast"]
    assert mc.MelCNN.cache_path("fast").name.endswith(f"-{fast.ident}.pt")
    # Another recipe of the same profile name is another file (a stale model is not loaded).
    assert dataclasses.replace(fast, epochs=fast.epochs + 1).ident != fast.ident
    assert dataclasses.replace(fast, eval_examples=fast.eval_examples + 1).ident == fast.ident
    assert fast_model.metadata["voice_engine"] == sounds.voice_engine()
    monkeypatch.setenv(checkpoint.CACHE_ENV, str(fast_cache))
    other = "formant" if sounds.voice_engine() != "formant" else "espeak-ng 1.51 (Debian)"
    monkeypatch.setattr(sounds, "voice_engine", lambda: other)
    with pytest.warns(RuntimeWarning, match="acoustic-sim train melcnn --profile fast"):
        mc.MelCNN.load_or_train("fast", progress=False)


def test_checkpoint_errors(fast_model, tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        mc.MelCNN.load(tmp_path / "missing.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(ConfigError):
        mc.MelCNN.load(bad)
    other = checkpoint.save_checkpoint(tmp_path / "other.pt", fast_model.state_dict(), {"kind": "ssdenet"})
    with pytest.raises(ConfigError, match="model kind"):
        mc.MelCNN.load(other)
    with pytest.raises(ConfigError, match="unknown MelCNN profile"):
        mc.MelCNN.load_or_train("huge")


def test_paper_network_shape_and_budget_layout():
    model = mc.MelCNN(mc.PROFILES["paper"].net)
    out = model(torch.zeros(2, 25, 128))
    assert out.shape == (2, 6)
    with pytest.raises(ConfigError):
        mc.NetConfig(conv1_kernel=(200, 5))


def test_three_independent_streams_training_validation_report():
    """Training data (stream 0), the validation windows the recipes were chosen on (1) and the
    windows ``eval paper`` reports on (2) come from different streams of the profile's seed;
    streams 0 and 1 are those of the two-stream split the cached models were trained with."""
    seed = mc.PROFILES["paper"].seed
    old = [np.random.default_rng(s).random(4) for s in np.random.SeedSequence(seed).spawn(2)]
    draws = [f("paper").random(4) for f in (mc.training_rng, mc.heldout_rng, mc.report_rng)]
    np.testing.assert_array_equal(draws[0], old[0])
    np.testing.assert_array_equal(draws[1], old[1])
    assert not np.allclose(draws[2], draws[0]) and not np.allclose(draws[2], draws[1])
