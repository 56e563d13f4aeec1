"""Labelled windows of the sound data: per-ear audibility labels, characteristic spectra, and
the generator of many windows.

Labels: audibility by energy, per ear
-------------------------------------
Generated sounds have onsets, silent gaps and decaying tails, so "class c was playing" is a
poor label for a 0.4 s window. Each class's ear signal is also analysed *alone*, and so is
the background, giving mel-band powers ``P_c(t, m)`` and ``P_noise(t, m)`` per frame t and
ear. The masker of class c is everything else, ``Q_c = mean_t P_noise + sum_{c' != c}
P_c'`` (the stationary background masks with its mean power per band: its frame-to-frame
dips are not holes a sound can be heard through). Class c is *audible* in a frame when it
stands ``audible_snr_db`` = 6 dB above its masker in at least ``audible_min_bands`` = 5
mel bands: clearly out of the noise, whose log power in a narrow band fluctuates by about
5 dB from frame to frame (a 0 dB, 3-band rule labelled sounds that nobody, and no network,
could see in the patch). With ``A`` the number of audible frames among the window's 25,
the target is the ramp

    y = clip((A - label_frames[0]) / (label_frames[1] - label_frames[0]), 0, 1)

with ``label_frames = (2, 6)``: 0 for at most two audible frames (a sound that only starts
in the newest frames, a last echo), 1 from 6 frames on (about 130 ms: frames are 46 ms
long and 16 ms apart), soft in between. The hard label, used for evaluation, is
``y >= 0.5``, i.e. ``A >= 4``. The binaural label is the maximum over the ears: a class is
present if either ear hears it.

Characteristic spectra
----------------------
For MelCNN's characteristic bins, every frame in which a class is audible at an ear adds
that class's power spectrum at that ear (1025 bins, the class's own signal), normalised to
unit sum so that loud and quiet frames count alike, into ``spectrum_sum[c]``.
"""

from __future__ import annotations

import numpy as np

from acoustic_sim.acoustics.microphone import FULL_SCALE_PA
from acoustic_sim.auditory.features import MEL_FRAMES, mel_power, normalize_log_mel
from acoustic_sim.auditory.frontend import N_BINS, analyze
from acoustic_sim.auditory.sound_data.brir_bank import BRIRBank
from acoustic_sim.auditory.sound_data.data_types import CLASSES, SoundDataConfig, SoundExamples, _progress
from acoustic_sim.auditory.sound_data.scene_mix import SoundPool, _scene
from acoustic_sim.errors import ConfigError


def _power_spectra(pressure: np.ndarray) -> np.ndarray:
    """Power spectra (K, 2, N_BINS) float32 of eardrum pressure (Pa) in full-scale units."""
    s = analyze(pressure / FULL_SCALE_PA).spectra
    return s.real**2 + s.imag**2


def audibility(mel_classes: np.ndarray, mel_noise: np.ndarray, cfg: SoundDataConfig) -> np.ndarray:
    """Which classes are audible in which frames, at each ear.

    Parameters
    ----------
    mel_classes : numpy.ndarray
        (C, K, 2, M) mel-band power of each class alone at the ears (full-scale units).
    mel_noise : numpy.ndarray
        (K, 2, M) mel-band power of the background alone.
    cfg : SoundDataConfig

    Returns
    -------
    numpy.ndarray
        bool (C, K, 2): the class exceeds its masker by ``audible_snr_db`` in at least
        ``audible_min_bands`` bands. The background, being stationary, masks with its mean
        power per band over the scene (its frame-to-frame dips are not holes a sound can
        be heard through: a band of one FFT bin fluctuates like an exponential variable);
        the other classes mask with their power in the same frame.
    """
    noise = mel_noise.mean(axis=0, keepdims=True)[None]  # (1, 1, 2, M)
    others = mel_classes.sum(axis=0, keepdims=True) - mel_classes + noise
    loud = (mel_classes > others * 10.0 ** (cfg.audible_snr_db / 10.0)) & (mel_classes > 0)
    return loud.sum(axis=-1) >= cfg.audible_min_bands


def scene_examples(cfg: SoundDataConfig, bank: BRIRBank, rng: np.random.Generator, *,
                   pool: SoundPool | None = None, dtype=np.float32) -> SoundExamples:
    """Draw one scene and return its windows (see the module docstring).

    Parameters
    ----------
    cfg : SoundDataConfig
    bank : BRIRBank
        Must hold every room of ``cfg.rooms``.
    rng : numpy.random.Generator
    pool : SoundPool, optional
        Where the sounds come from; default: fresh instances for this scene only.
    dtype : numpy dtype
        dtype of the patches (float32; float16 halves the memory of large training sets).

    Returns
    -------
    SoundExamples
        ``cfg.windows_per_scene()`` windows.
    """
    missing = [r for r in cfg.rooms if r not in bank.brirs]
    if missing:
        raise ConfigError(f"the BRIR bank has no BRIRs for rooms {missing}")
    if pool is None:
        pool = SoundPool(seconds=cfg.sound_seconds[1], size=1, reuse=1)
    sc = _scene(cfg, bank, rng, pool)
    spectra = analyze(sc.digital).spectra  # (K, 2, F)
    mel_total = mel_power(spectra)  # (K, 2, M)
    volume = np.mean(spectra.real.astype(np.float64) ** 2 + spectra.imag.astype(np.float64) ** 2, axis=-1)  # (K, 2)
    n_frames = spectra.shape[0]
    ends = np.arange(cfg.first_window_frame - 1, n_frames, cfg.window_hop_frames)  # 0-based last frame
    w = ends.size
    idx = ends[:, None] + np.arange(-MEL_FRAMES + 1, 1)[None, :]  # (W, 25)

    patches = normalize_log_mel(mel_total[idx].transpose(0, 2, 1, 3)).astype(dtype)  # (W, 2, 25, M)
    volumes = volume[idx].mean(axis=1)  # (W, 2)

    n_cls = len(CLASSES)
    targets = np.zeros((w, 2, n_cls), np.float32)
    spectrum_sum = np.zeros((n_cls, N_BINS))
    spectrum_frames = np.zeros(n_cls, np.int64)
    if sc.classes:
        power = [_power_spectra(e) for e in sc.ears]  # each (K, 2, F)
        mel_cls = np.stack([mel_power(np.sqrt(p)) for p in power])  # (C, K, 2, M)
        mel_noise = mel_power(np.sqrt(_power_spectra(sc.noise)))
        audible = audibility(mel_cls, mel_noise, cfg)  # (C, K, 2)
        count = audible[:, idx].sum(axis=2)  # (C, W, 2)
        a0, a1 = cfg.label_frames
        ramp = np.clip((count - a0) / (a1 - a0), 0.0, 1.0).astype(np.float32)
        for j, c in enumerate(sc.classes):
            targets[:, :, c] = ramp[j]
            frames = power[j][audible[j]]  # (n, F) spectra of audible (frame, ear) pairs
            totals = frames.sum(axis=-1, keepdims=True)
            ok = totals[:, 0] > 0
            spectrum_sum[c] += (frames[ok] / totals[ok]).sum(axis=0)
            spectrum_frames[c] += int(ok.sum())
    labels = targets.max(axis=1) >= 0.5
    return SoundExamples(patches, targets, labels, volumes, np.full(w, sc.room, np.int8), spectrum_sum, spectrum_frames)


def generate_examples(n_examples: int, rng: np.random.Generator, *, config: SoundDataConfig | None = None,
                      bank: BRIRBank | None = None, brirs_per_room: int = 8, dtype=np.float32,
                      progress: bool = False) -> SoundExamples:
    """Generate ``n_examples`` labelled windows from fresh random scenes.

    Parameters
    ----------
    n_examples : int
        Number of windows, >= 1 (the last scene's surplus windows are dropped).
    rng : numpy.random.Generator
        The only source of randomness: positions, sounds, levels, noise. Use independent
        streams for training and evaluation (e.g. ``SeedSequence(seed).spawn``).
    config : SoundDataConfig, optional
        Scene parameters (default ``SoundDataConfig()``).
    bank : BRIRBank, optional
        BRIRs to use; default: a new bank of ``brirs_per_room`` BRIRs per room, drawn from
        ``rng`` first (so held-out data also has unseen source positions).
    brirs_per_room : int
        Size of the default bank per room.
    dtype : numpy dtype
        dtype of the patches.
    progress : bool
        Show progress bars.

    Returns
    -------
    SoundExamples
    """
    if isinstance(n_examples, bool) or not isinstance(n_examples, (int, np.integer)) or n_examples < 1:
        raise ConfigError(f"n_examples must be a positive integer, got {n_examples!r}")
    if not isinstance(rng, np.random.Generator):
        raise ConfigError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    cfg = SoundDataConfig() if config is None else config
    if bank is None:
        bank = BRIRBank.build(rng, rooms=cfg.rooms, per_room=brirs_per_room, progress=progress)
    pool = SoundPool(seconds=cfg.sound_seconds[1], size=cfg.pool_size, reuse=cfg.pool_reuse)
    parts: list[SoundExamples] = []
    have = 0
    bar = _progress(int(n_examples), "sound examples", progress)
    while have < n_examples:
        ex = scene_examples(cfg, bank, rng, pool=pool, dtype=dtype)
        take = min(len(ex), n_examples - have)
        parts.append(ex)
        have += take
        bar.update(take)
    bar.close()
    return _concat(parts, int(n_examples))


def _concat(parts: list[SoundExamples], n: int) -> SoundExamples:
    return SoundExamples(
        patches=np.concatenate([p.patches for p in parts])[:n],
        targets=np.concatenate([p.targets for p in parts])[:n],
        labels=np.concatenate([p.labels for p in parts])[:n],
        volumes=np.concatenate([p.volumes for p in parts])[:n],
        room=np.concatenate([p.room for p in parts])[:n],
        spectrum_sum=np.sum([p.spectrum_sum for p in parts], axis=0),
        spectrum_frames=np.sum([p.spectrum_frames for p in parts], axis=0),
    )
