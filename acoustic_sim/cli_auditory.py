"""``acoustic-sim`` subcommands of the auditory pipeline: train, localize, detect.

Kept apart from ``cli.py`` so each file stays readable; ``cli.build_parser`` calls
:func:`add_parsers` (and ``eval``'s, in :mod:`acoustic_sim.cli_eval`).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import check_writable

HRTF_HELP = ("'kemar' (bundled MIT KEMAR, mirror-symmetric ears), 'musashi' (the robot's ears: KEMAR with the right pinna "
             "tilted 10 deg, so that the median plane has interaural cues), 'spherical' (rigid sphere, no pinna) or a "
             "SimpleFreeFieldHRIR .sofa file")


def add_parsers(sub) -> None:
    t = sub.add_parser(
        "train",
        help="train (and cache) the SSDENet bank or the MelCNN detector, or learn a task policy",
        description="ssdenet, melcnn: train a model from scratch and write it to the cache that the pipeline "
        "loads (or to --out). Models are otherwise trained on first use; this rebuilds them. "
        "policy: learn a policy for --task with stable-baselines3 PPO, from the env alone (skill action "
        "mode and shaped reward by default, the fast auditory models), and write OUT/policy.zip, "
        "OUT/policy.json (metadata), OUT/progress.csv (per-update metrics), OUT/episodes.csv and "
        "OUT/learning_curve.png; run it with `acoustic-sim run TASK --policy learned:OUT`.",
    )
    t.add_argument("model", choices=("ssdenet", "melcnn", "policy"), help="which model")
    t.add_argument("--hrtf", default="kemar", help=f"SSDENet only: the ears, {HRTF_HELP}")
    t.add_argument("--profile", default=None, choices=("paper", "fast"),
                   help="model size (default paper; fast: small, for tests); policy: the env's auditory models (default fast)")
    t.add_argument("--seed", type=int, default=None,
                   help="SSDENet: training seed (default: the profile's); policy: the learner's and the envs' seed (default 0)")
    t.add_argument("--out", type=Path, default=None, help="checkpoint path (default: the cache); policy: output folder")
    from apps import learn  # the CLI's entry may reach up to the apps

    learn.add_parser(t)
    t.set_defaults(func=cmd_train)

    loc = sub.add_parser(
        "localize",
        help="estimate the direction of the sound in a 2-channel WAV (JSON lines)",
        description="Runs the ear front end on a WAV in the scale that `render` writes and prints one JSON "
        "object per ear frame (t, azimuth_deg, elevation_deg: a running estimate over the last 25 "
        "frames; null where nothing could be estimated), then a last object with \"overall\": true "
        "holding the estimate for the whole file. Directions are in the head frame: azimuth from the "
        "nose, left positive; elevation up positive. --method ssdenet (the paper's networks) loads the "
        "SSDENet bank of --hrtf and the MelCNN (its characteristic bins, for --sound), training them on "
        "first use; music (HRTF steering vectors) and gcc-phat (interaural time difference, calibrated on "
        "the HRTF: front half of the horizontal plane only) use the HRTF alone and load or train no model. "
        "The file is read block by block and the lines are written as it is read: memory does not grow "
        "with the file's length.",
    )
    loc.add_argument("wav", type=Path, help="2-channel WAV (left, right)")
    loc.add_argument("--hrtf", default="kemar", help=f"the ears the recording was made with: {HRTF_HELP}")
    loc.add_argument("--method", default="ssdenet", choices=("ssdenet", "music", "gcc-phat"), help="localization method (default ssdenet)")
    loc.add_argument("--profile", default="paper", choices=("paper", "fast"),
                     help="model size for --method ssdenet (default paper; music and gcc-phat use no model)")
    loc.add_argument("--ssdenet", type=Path, default=None,
                     help="--method ssdenet only: use this SSDENet checkpoint instead of the cached one")
    loc.add_argument("--sound", default=None, help="--method ssdenet only: use only the characteristic bins of this sound class")
    # Literal, as the SSDENet module (torch) is not imported for --help; a test checks it is ssdenet.FUSIONS.
    loc.add_argument("--fusion", default=None, choices=("product", "sum"),
                     help="--method ssdenet only: how SSDENet fuses a frame's bins: product (default: n times their geometric mean, "
                     "which one confidently wrong bin cannot outvote) or sum (the paper's equation)")
    loc.set_defaults(func=cmd_localize)

    det = sub.add_parser(
        "detect",
        help="which of the six sound classes a 2-channel WAV contains (JSON lines)",
        description="Prints one JSON object per ear frame with t and the fused class probabilities "
        "(MelCNN on the last 25 frames of each ear, weighted by ear volume), then a last object with "
        "\"overall\": true: per class the largest probability over the file and the detected classes. "
        "The file is read block by block and the lines are written as it is read: memory does not grow "
        "with the file's length.",
    )
    det.add_argument("wav", type=Path, help="2-channel WAV (left, right)")
    det.add_argument("--profile", default="paper", choices=("paper", "fast"), help="model size (default paper)")
    det.add_argument("--threshold", type=float, default=0.5, help="detection threshold (default 0.5)")
    det.set_defaults(func=cmd_detect)


def _check_wav(path: Path) -> None:
    """Refuse, before any model is built, a WAV that localize/detect could not use: missing,
    not a sound file, not 2 channels, shorter than one ear frame, or holding NaN, infinite or
    absurdly large samples (a float file is scanned in blocks, so a long file is not held in
    memory for the check; integer PCM cannot hold such samples)."""
    import soundfile as sf

    from acoustic_sim.auditory.frontend import MAX_ABS_SAMPLE
    from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample

    if not path.is_file():
        raise ConfigError(f"{path}: no such file" if not path.exists() else f"{path}: not a regular file")
    try:
        with sf.SoundFile(path) as f:
            if f.channels != 2:
                raise ConfigError(f"{path}: needs 2 channels (left, right), has {f.channels}")
            if f.frames == 0:
                raise ConfigError(f"{path}: contains no samples")
            if -(-f.frames * SAMPLE_RATE // f.samplerate) < frame_end_sample(1):
                raise ConfigError(f"{path}: {f.frames} samples at {f.samplerate} Hz are shorter than one ear frame "
                                  f"({frame_end_sample(1)} samples at {SAMPLE_RATE} Hz)")
            if f.subtype.startswith("PCM_") or f.subtype in ("ULAW", "ALAW"):
                return
            for block in f.blocks(blocksize=1 << 16, dtype="float32"):
                if not np.all(np.isfinite(block)):
                    raise ConfigError(f"{path}: holds NaN or infinite samples")
                if np.max(np.abs(block)) > MAX_ABS_SAMPLE:
                    raise ConfigError(f"{path}: holds a sample beyond {MAX_ABS_SAMPLE:.0e} full scale (1.0 = the ADC's "
                                      "full scale, as render writes)")
    except (RuntimeError, sf.LibsndfileError) as exc:
        raise ConfigError(f"{path}: not a readable audio file ({str(exc).splitlines()[0]})") from None


def cmd_train(args) -> int:
    if args.seed is not None and args.seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {args.seed}")
    if args.model == "policy":
        from apps.learn import cmd_train_policy

        return cmd_train_policy(args)
    if args.task is not None:
        raise ConfigError("--task and the other policy options apply to `train policy` only")
    args.profile = args.profile or "paper"
    if args.out is not None:
        check_writable(args.out, what="--out")  # before the training, not after
    if args.model == "ssdenet":
        from acoustic_sim.auditory.ssdenet import train_command

        info = train_command(args.hrtf, args.profile, args.out, seed=args.seed)
    else:
        if args.hrtf != "kemar" or args.seed is not None:
            raise ConfigError("--hrtf and --seed apply to ssdenet only (MelCNN is trained on KEMAR renders with its profile's seed)")
        info = _train_melcnn(args.profile, args.out)
    print(json.dumps(info))
    return 0


def _train_melcnn(profile: str = "paper", out=None) -> dict:
    """What ``acoustic-sim train melcnn`` runs: train afresh and write the checkpoint.

    Parameters
    ----------
    profile : str
        ``paper`` or ``fast``.
    out : path-like, optional
        Checkpoint path; default the cache file that :meth:`MelCNN.load_or_train` reads.

    Returns
    -------
    dict
        JSON-ready summary: ``kind``, ``profile``, ``path``, ``train_seconds`` (all of
        it, data generation included), ``data_seconds`` (of which data), ``n_examples``, ``final_loss``, ``characteristic_bins`` (number
        of bins per class) and ``frame_ms`` (both ears, this machine's current threads).
    """
    from acoustic_sim.auditory.melcnn import KIND, MelCNN, frame_time_ms, get_profile, train

    prof = get_profile(profile)
    model = train(prof, progress=True)
    path = model.save(MelCNN.cache_path(prof.name) if out is None else Path(out))
    m = model.metadata
    return {
        "kind": KIND, "profile": prof.name, "path": str(path), "train_seconds": m["train_seconds"],
        "data_seconds": m["data_seconds"], "n_examples": m["n_examples"], "final_loss": round(m["final_loss"], 5),
        "characteristic_bins": {k: int(v.size) for k, v in model.characteristic_bins.items()},
        "frame_ms": round(frame_time_ms(model), 3),
    }


def _pipeline(hrtf: str, profile: str, ssdenet_path: Path | None = None, fusion: str = "product"):
    from acoustic_sim.acoustics.hrtf import HRTF
    from acoustic_sim.auditory.melcnn import MelCNN
    from acoustic_sim.auditory.pipeline import AuditoryPipeline
    from acoustic_sim.auditory.ssdenet import SSDENetBank
    from acoustic_sim.directions import DirectionGrid

    ears = HRTF.load(hrtf)
    grid = DirectionGrid.paper(ears)
    if ssdenet_path is not None:
        bank = SSDENetBank.load(ssdenet_path, ears, grid)
    else:
        bank = SSDENetBank.load_or_train(ears, grid, profile)
    return AuditoryPipeline(hrtf=ears, grid=grid, ssdenet=bank, melcnn=MelCNN.load_or_train(profile), fusion=fusion)


def cmd_localize(args) -> int:
    _check_wav(args.wav)
    ssdenet = args.method == "ssdenet"
    if not ssdenet:
        # MUSIC and GCC-PHAT use the HRTF alone: these options would be ignored.
        for flag, value in (("--ssdenet", args.ssdenet), ("--sound", args.sound), ("--fusion", args.fusion)):
            if value is not None:
                raise ConfigError(f"{flag} applies to --method ssdenet only, not {args.method}")
    if args.ssdenet is not None and not args.ssdenet.is_file():
        raise ConfigError(f"--ssdenet {args.ssdenet}: no such file")
    if args.sound is not None:
        from acoustic_sim.acoustics.sounds import SOUND_CLASSES

        if args.sound not in SOUND_CLASSES:
            raise ConfigError(f"--sound: unknown sound class {args.sound!r}; valid: {', '.join(SOUND_CLASSES)}")
    from acoustic_sim.auditory.features import MEL_FRAMES
    from acoustic_sim.auditory.recording import BaselineTrack, SSDENetTrack, frame_chunks, wav_blocks

    fusion = args.fusion or "product"
    if ssdenet:
        track = SSDENetTrack(_pipeline(args.hrtf, args.profile, args.ssdenet, fusion), sound=args.sound,
                             window=MEL_FRAMES)
    else:
        from acoustic_sim.acoustics.hrtf import HRTF
        from acoustic_sim.directions import DirectionGrid

        ears = HRTF.load(args.hrtf)
        track = BaselineTrack(args.method, ears, DirectionGrid.paper(ears), window=MEL_FRAMES)
    out = sys.stdout
    for frames in frame_chunks(wav_blocks(args.wav)):  # rows are written as the file is read
        for t, est in track.push(frames):
            row = {"t": round(t, 6), "azimuth_deg": None, "elevation_deg": None}
            if est is not None:
                row.update(azimuth_deg=round(est.azimuth_deg, 2), elevation_deg=round(est.elevation_deg, 2))
            out.write(json.dumps(row) + "\n")
    overall = track.overall()
    last = {"overall": True, "method": args.method, "azimuth_deg": None, "elevation_deg": None, "frames": track.frames}
    if ssdenet:
        last["fusion"] = fusion
    if overall is not None:
        last.update(azimuth_deg=round(overall.azimuth_deg, 2), elevation_deg=round(overall.elevation_deg, 2),
                    confidence=round(overall.confidence, 4))
    out.write(json.dumps(last) + "\n")
    return 0


def cmd_detect(args) -> int:
    _check_wav(args.wav)
    if not 0.0 < args.threshold < 1.0:
        raise ConfigError(f"--threshold must be in (0, 1), got {args.threshold}")
    from acoustic_sim.auditory.melcnn import MelCNN
    from acoustic_sim.auditory.recording import DetectTrack, frame_chunks, wav_blocks

    cnn = MelCNN.load_or_train(args.profile)
    track = DetectTrack(cnn)
    for frames in frame_chunks(wav_blocks(args.wav)):  # rows are written as the file is read
        times, probs = track.push(frames)
        for t, p in zip(times, probs):
            sys.stdout.write(json.dumps({"t": round(float(t), 6), **{c: round(float(v), 4) for c, v in zip(cnn.classes, p)}}) + "\n")
    overall = track.overall()
    detected = [c for c, v in zip(cnn.classes, overall) if v >= args.threshold]
    sys.stdout.write(json.dumps({"overall": True, **{c: round(float(v), 4) for c, v in zip(cnn.classes, overall)},
                                 "detected": detected, "threshold": args.threshold}) + "\n")
    return 0
