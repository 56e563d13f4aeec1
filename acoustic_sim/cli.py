"""The ``acoustic-sim`` command.

Every subcommand has ``--help``. Bad arguments and bad files end with a one-line error on
stderr and exit status 2, never a traceback (set ``ACOUSTIC_SIM_DEBUG=1`` to see one).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from acoustic_sim.errors import AcousticSimError
from acoustic_sim.files import check_writable, write_text


def _vector(text: str) -> np.ndarray:
    try:
        v = np.array([float(t) for t in text.split(",")])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z in metres, got {text!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z, got {text!r}")
    return v


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def _finite(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not np.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (the usage is one --help away), as every other error,
    that names the subcommand even for arguments it does not know (argparse leaves those to
    the top-level parser)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def parse_known_args(self, args=None, namespace=None):
        namespace, extras = super().parse_known_args(args, namespace)
        if not hasattr(namespace, "_innermost_parser"):  # the innermost subcommand finishes first
            namespace._innermost_parser = self
        return namespace, extras


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="acoustic-sim",
        description="A simulated humanoid acoustic testbed: binaural ears with pinnae, rooms, and the "
        "Omura et al. 2022 auditory pipeline.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser(
        "render",
        help="render a sound at a direction in a room to a 2-channel WAV",
        description="Render one source at a direction and distance in the head frame to the two ears "
        "(left, right) of a head in a room, through the HRTF, image sources and a diffuse tail, the "
        "room's background noise and the ear unit's microphone and 24-bit ADC. Writes a float32 WAV "
        "at 44.1 kHz whose full scale 1.0 is the microphone's overload point (132 dB SPL). With "
        "--sound impulse, writes the binaural room impulse response instead (ear pressure per pascal "
        "at 1 m; no noise, no microphone).",
    )
    r.add_argument("--hrtf", default="kemar", help="'kemar' (bundled MIT KEMAR), 'musashi' (KEMAR, right pinna tilted 10 deg), 'spherical' (rigid sphere, no pinna) or a SimpleFreeFieldHRIR .sofa file")
    r.add_argument("--room", default="anechoic", help="anechoic, car_cabin, lab, conference or shoebox:LxWxH (metres; needs --rt60)")
    r.add_argument("--rt60", type=_positive, default=None, help="reverberation time in seconds for shoebox (and to override lab/conference)")
    r.add_argument("--listener", type=_vector, default=None, help="head centre X,Y,Z in metres (room frame); default: the room's listening position")
    r.add_argument("--sound", default="white_noise", help="a sound class (car_horn, reverse_alarm, ratchet, gearshift, key_turning, human_voice), white_noise, a WAV file, or 'impulse'")
    r.add_argument("--level", type=_finite, default=70.0, help="source level in dB SPL at 1 m (default 70)")
    r.add_argument("--azimuth", type=_finite, default=0.0,
                   help="source azimuth in degrees, head frame, left positive (default 0); read modulo 360, so a value "
                   "outside [-180, 180] wraps (190 is -170)")
    r.add_argument("--elevation", type=_finite, default=0.0,
                   help="source elevation in degrees, up positive, -90..90 (default 0; outside that range is an error, "
                   "not wrapped)")
    r.add_argument("--distance", type=_positive, default=1.5, help="source distance from the head centre in metres (default 1.5)")
    r.add_argument("--head-yaw", type=_finite, default=0.0, help="head yaw in degrees in the room (0 faces +x, left positive)")
    r.add_argument("--seconds", type=_positive, default=1.0, help="length of the rendering in seconds (default 1; ignored for impulse)")
    r.add_argument("--seed", type=int, default=0, help="random seed, >= 0: same seed, same file byte for byte (default 0)")
    r.add_argument("--out", type=Path, required=True, help="output WAV path")
    r.set_defaults(func=cmd_render)

    m = sub.add_parser(
        "measure-hrtf",
        help="simulate the paper's HRTF measurement in a room and write a SOFA file",
        description="For every direction of the paper's grid, play white noise from a loudspeaker at the "
        "given distance in the room, record both ears through the microphone model, and estimate the "
        "transfer function as the paper did (so the result contains the room). Writes a "
        "SimpleFreeFieldHRIR SOFA file that --hrtf accepts.",
    )
    m.add_argument("--hrtf", default="kemar", help="the ears being measured: kemar, musashi, spherical or a .sofa file")
    m.add_argument("--room", default="conference", help="room preset (default: conference, the paper's measurement room)")
    m.add_argument("--rt60", type=_positive, default=None, help="reverberation time in seconds for shoebox rooms")
    m.add_argument("--distance", type=_positive, default=1.5, help="loudspeaker distance in metres (default 1.5)")
    m.add_argument("--seconds", type=_positive, default=1.0, help="white-noise length per direction in seconds (default 1)")
    m.add_argument("--taps", type=int, default=512,
                   help="length of the measured responses in samples, a gate: reflections arriving later are "
                        "left out (default 512 = 11.6 ms; `eval paper` uses 128, before the first reflection)")
    m.add_argument("--max-directions", type=int, default=None, help="measure only this many directions (evenly spread), for quick runs")
    m.add_argument("--seed", type=int, default=0, help="random seed, >= 0 (default 0)")
    m.add_argument("--out", type=Path, required=True, help="output .sofa path")
    m.set_defaults(func=cmd_measure_hrtf)

    b = sub.add_parser("bench", help="run a benchmark and write JSON", description="Performance benchmarks; each writes a JSON file.")
    bsub = b.add_subparsers(dest="bench", required=True, metavar="BENCH")
    br = bsub.add_parser(
        "render",
        help="renderer real-time factors and speed-up against pyroomacoustics",
        description="Measures the real-time factor of streaming the car cabin with 1 and 3 sources while "
        "the head turns (a new pose every 16 ms), and the speed-up against pyroomacoustics "
        "re-simulating the same scene (same SOFA file as its measured directivity, same image-source "
        "order) for every pose.",
    )
    br.add_argument("--out", type=Path, default=Path("bench/render.json"), help="output JSON (default bench/render.json)")
    br.add_argument("--quick", action="store_true", help="shorter runs (for tests): numbers are noisier")
    br.set_defaults(func=cmd_bench_render)
    bw = bsub.add_parser(
        "world",
        help="physics and coupling time per 16 ms control step, cabin and room scenes",
        description="Measures world_step_ms for the cabin and room scenes while the robot moves as in a task: "
        "8 physics steps of 2 ms plus the coupling (mechanism traces, sound events, ear and source poses in "
        "the acoustic room's frame, ego-noise level), without audio rendering, per 16 ms control step. "
        "Target: at most 1 ms.",
    )
    bw.add_argument("--out", type=Path, default=Path("bench/world.json"), help="output JSON (default bench/world.json)")
    bw.add_argument("--quick", action="store_true", help="shorter runs (for tests): numbers are noisier")
    bw.set_defaults(func=cmd_bench, bench_module="bench_world")
    bv = bsub.add_parser(
        "viz",
        help="rerun logging cost: ms per frame and MB per minute",
        description="Records 60 s of a cabin episode (scene, percepts, spectrograms, audio, 320x240 eye camera) "
        "to an .rrd; writes log_ms_per_frame and rrd_mb_per_min. Targets: 1 ms per frame, 30 MB per minute. "
        "Without --quick, also 'episode': the cost of recording three real ReverseAlarm episodes (fast models) "
        "through the runner's hook, as `acoustic-sim run --rrd` does, and of rendering one eye-camera image.",
    )
    bv.add_argument("--out", type=Path, default=Path("bench/viz.json"), help="output JSON (default bench/viz.json)")
    bv.add_argument("--quick", action="store_true", help="10 s instead of 60 s")
    bv.set_defaults(func=cmd_bench, bench_module="bench_viz")
    be = bsub.add_parser(
        "env",
        help="env steps per second of the hearing tasks (paper, fast, a vector of 2)",
        description="Steps each task env with the scripted policy (physics, rendering, microphone, pipeline, "
        "observation) for the paper and fast profiles, and a vector of 2 envs (async and sync); writes "
        "env_steps_per_s. Targets: 62.5 (paper), 300 (fast). For a learner: reset_ms per task with its parts, "
        "skill-mode steps/s with resets, and 1-vs-2-worker scaling (targets 50 ms, 500 steps/s fast, 1.7x).",
    )
    be.add_argument("--out", type=Path, default=Path("bench/env.json"), help="output JSON (default bench/env.json)")
    be.add_argument("--quick", action="store_true", help="fast profile only, short runs (for tests)")
    be.add_argument("--profile", choices=("fast", "paper"), default=None,
                    help="measure this auditory profile only (default both; paper trains its models first if the cache lacks them)")
    be.set_defaults(func=cmd_bench, bench_module="bench_env")
    bp = bsub.add_parser(
        "pipeline",
        help="auditory pipeline time per ear frame and SSDENet training time",
        description="Measures frame_ms_median (one ear frame, both ears: front end, MelCNN and SSDENet over the "
        "valid bins, paper profile, 2 threads) on a reverse alarm in the car cabin, ssdenet_train_s (paper "
        "profile, trained afresh) and peak memory. Targets: 4 ms per frame, 600 s of training.",
    )
    bp.add_argument("--out", type=Path, default=Path("bench/pipeline.json"), help="output JSON (default bench/pipeline.json)")
    bp.add_argument("--quick", action="store_true", help="fast profile and short runs (for tests)")
    bp.set_defaults(func=cmd_bench, bench_module="bench_pipeline")

    d = sub.add_parser(
        "demo",
        help="one ReverseAlarm episode with the scripted policy, told in words (what `make demo` runs)",
        description="Runs one episode of the ReverseAlarm task (the robot in the car cabin pushes the gearshift "
        "into R; the reverse alarm starts in front of it; it must let go within 1 s, and not for another vehicle's "
        "beeper behind or beside) with the scripted policy, which lets go when it hears the alarm from the front. "
        "Prints what happened: when the alarm started, when the robot recognized it and from which direction "
        "(from the percepts in its observations), what else it heard, when the hand let go, and the outcome "
        "(success, or the failure and why). Writes OUT/demo.png (left and right mel spectrograms, class "
        "probabilities and the alarm's estimated lateral angle from the head over time, with the events marked), "
        "OUT/demo.rrd (a rerun recording: acoustic-sim play OUT/demo.rrd), OUT/demo.wav (what the ears heard) and OUT/demo.json. The "
        "first run trains the chosen profile's models and caches them (about three minutes for fast on a CPU, with a "
        "progress bar); later runs take seconds.",
    )
    d.add_argument("--out", type=Path, default=Path("runs"), help="output folder (default runs/)")
    d.add_argument("--seed", type=int, default=0, help="episode seed, >= 0 (default 0): same seed, same episode")
    d.add_argument("--profile", choices=("fast", "paper"), default="fast",
                   help="auditory models: fast (default; small networks, trained in about three minutes on a CPU) or paper "
                   "(the paper's networks; several minutes of training the first time)")
    d.set_defaults(func=cmd_demo)

    from acoustic_sim import cli_auditory, cli_eval, cli_world

    cli_auditory.add_parsers(sub)
    cli_eval.add_parsers(sub)
    cli_world.add_parsers(sub)
    from apps import deaf_search, runner

    runner.add_parsers(sub)
    deaf_search.add_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, extras = parser.parse_known_args(argv)
    if extras:
        args._innermost_parser.error(f"unrecognized arguments: {' '.join(extras)}")
    try:
        return int(args.func(args) or 0)
    except (AcousticSimError, OSError) as err:
        if os.environ.get("ACOUSTIC_SIM_DEBUG"):
            raise
        msg = str(err).splitlines()[0] if str(err) else type(err).__name__
        print(f"acoustic-sim {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"acoustic-sim {args.command}: interrupted", file=sys.stderr)
        return 130


# -- commands ----------------------------------------------------------------------------------


def cmd_render(args) -> int:
    from acoustic_sim.acoustics.scene import render_to_wav

    info = render_to_wav(
        hrtf=args.hrtf, room=args.room, rt60=args.rt60, listener=args.listener, sound=args.sound, level_db=args.level,
        azimuth_deg=args.azimuth, elevation_deg=args.elevation, distance_m=args.distance, head_yaw_deg=args.head_yaw,
        seconds=args.seconds, seed=args.seed, out=args.out,
    )
    print(json.dumps(info))
    return 0


def cmd_measure_hrtf(args) -> int:
    from acoustic_sim.acoustics.measure import measure_hrtf

    info = measure_hrtf(
        hrtf=args.hrtf, room=args.room, rt60=args.rt60, distance_m=args.distance, seconds=args.seconds,
        taps=args.taps, max_directions=args.max_directions, seed=args.seed, out=args.out,
    )
    print(json.dumps(info))
    return 0


def cmd_bench_render(args) -> int:
    args.bench_module = "bench_render"
    return cmd_bench(args)


def cmd_bench(args) -> int:
    import importlib

    check_writable(args.out, what="--out")  # before the benchmark's minutes, not after
    run = importlib.import_module(f"benchmarks.{args.bench_module}").run
    kwargs = {"profile": args.profile} if getattr(args, "profile", None) else {}
    result = run(quick=args.quick, **kwargs)
    write_text(args.out, json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


def cmd_demo(args) -> int:
    from apps.demo import run_demo

    t0 = time.perf_counter()
    summary = run_demo(out=args.out, seed=args.seed, profile=args.profile)
    print(summary)
    print(f"(demo took {time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
