"""``acoustic-sim eval`` subcommands: the paper's experiments, the active-hearing trials, the
task table and the README's tables.

Kept apart from :mod:`acoustic_sim.cli_auditory` so each file stays readable;
``cli.build_parser`` calls :func:`add_parsers` after the auditory subcommands'.
"""

from __future__ import annotations

import json
from pathlib import Path

from acoustic_sim.cli_auditory import HRTF_HELP
from acoustic_sim.errors import ConfigError
from acoustic_sim.files import check_writable_folder
from apps.eval_tasks import EVAL_SEED, design_seeds_text


def add_parsers(sub) -> None:
    ev = sub.add_parser(
        "eval",
        help="reproduce the paper's experiments",
        description="Experiments as commands; each writes JSON, a REPORT.md and PNG figures.",
    )
    esub = ev.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")
    ep = esub.add_parser(
        "paper",
        help="all experiments of Omura et al. 2022",
        description="pinna.json (median-plane responses with and without pinnae), hrtf_ild_ipd.json (ILD/IPD "
        "at the paper's six frequencies), localization.json (simulation: 13 signals x every grid "
        "direction; room: white noise in the lab room with networks trained on the HRTF measured in "
        "the conference room), detection.json (MelCNN F1), REPORT.md and figures.",
    )
    ep.add_argument("--out", type=Path, required=True, help="output folder")
    ep.add_argument("--hrtf", default="musashi", help=f"the robot's ears (default musashi): {HRTF_HELP}")
    ep.add_argument("--quick", action="store_true", help="fewer directions and sounds, small models (under a minute once the small MelCNN is cached; for tests)")
    ep.add_argument("--seed", type=int, default=0, help="random seed")
    ep.set_defaults(func=cmd_eval_paper)
    ea = esub.add_parser(
        "active",
        help="does one head turn resolve front and back? (the world-frame tracker)",
        description="Plays white noise and each of the six classes from directions drawn from the seed (on the "
        "horizontal plane and off it), in the lab room (1.5 m) and the car cabin (0.8 m or nearer a wall), with the "
        "head still or turning once by 10, 15, 30 or 45 deg during the sound. Scores the pipeline's head-frame "
        "estimate on the still head and the world-frame tracker's after each turn: the front-back confusion rate, "
        "the mean azimuth error and the time to a front-back decision. Writes OUT/active.json, OUT/trials.json, "
        "OUT/pairs.json (two sources at once), OUT/REPORT.md and OUT/active_confusion.png. A trial took about 0.4 s on one core (fast models): the default "
        "(150 directions x 7 sounds x 5 head movements x 2 rooms, 10500 trials) about 70 min; --horizontal 30 "
        "--off-plane 10 (2800 trials) took 18.5 min.",
    )
    ea.add_argument("--out", type=Path, required=True, help="output folder")
    ea.add_argument("--hrtf", default="kemar", help=f"the robot's ears (default kemar): {HRTF_HELP}")
    ea.add_argument("--profile", default="fast", choices=("paper", "fast"),
                    help="model size (default fast: the paper models take hours to train without a GPU)")
    ea.add_argument("--horizontal", type=int, default=None, help="directions on the horizontal plane per room (default 100)")
    ea.add_argument("--off-plane", type=int, default=None, help="directions off the horizontal plane per room (default 50)")
    ea.add_argument("--room", action="append", default=None, dest="rooms", choices=("lab", "car_cabin", "anechoic"),
                    help="a room (repeat for several; default lab and car_cabin)")
    ea.add_argument("--sound", action="append", default=None, dest="sounds",
                    help="a sound (repeat for several; default white_noise and the six classes)")
    ea.add_argument("--precedence", default=None,
                    choices=("wavefront", "ratio", "coherence", "wavefront+coherence", "none"),
                    help="the pipeline's evidence rule (default wavefront+coherence; see AuditoryPipeline)")
    ea.add_argument("--pairs", type=int, default=None,
                    help="two-source scenes per room (anechoic, car_cabin, lab; default 50; 0: none): alarm + voice, "
                    "ratchet + horn, gearshift + key turning at once, at least 30 deg apart")
    ea.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ea.add_argument("--quick", action="store_true", help="3 + 1 directions, 2 sounds, turns of 0 and 30 deg, 1 two-source scene per room (for tests)")
    ea.set_defaults(func=cmd_eval_active)
    et = esub.add_parser(
        "tasks",
        help="every task with the scripted, oracle, blind, deaf and random policies",
        description="What hearing the direction is worth: runs each task (reverse-alarm, parking-brake, "
        "call-response) with each policy (scripted: from the percepts; oracle: from the ground truth; "
        "blind: classes without directions; deaf: never reads the percept; random) on the same seeds, and writes OUT/<task>/<policy>/episodes.json, "
        "OUT/tasks.json, OUT/REPORT.md (the table) and OUT/tasks.png (bar charts), the rates with their 95 % "
        "intervals. A full run (100 episodes each, paper models) took 14 minutes on 2 cores with three policies; "
        "five take about 24.",
    )
    et.add_argument("--out", type=Path, required=True, help="output folder")
    et.add_argument("--profile", default="paper", choices=("paper", "fast"), help="model size (default paper)")
    et.add_argument("--episodes", type=int, default=None, help="episodes per task and policy (default 100; 3 with --quick)")
    et.add_argument("--seed", type=int, default=EVAL_SEED,
                    help=f"seed of the first episode (default {EVAL_SEED}: held-out episodes; the policies were tuned on "
                    f"seeds {design_seeds_text()}; the regression tests run 100-119)")
    et.add_argument("--quick", action="store_true", help="3 episodes each with the fast models (for tests)")
    et.add_argument("--policy", action="append", default=None, metavar="POLICY", dest="policies",
                    help="a policy to run (repeat for several): a name (scripted, oracle, blind, deaf, random, "
                    "random-hold) or module:Class, an object with reset(obs, info, seed) and act(obs, info); "
                    "default scripted, oracle, blind, deaf and random")
    et.set_defaults(func=cmd_eval_tasks)
    er = esub.add_parser(
        "readme",
        help="copy a finished run's tables and figures into the README",
        description="Replaces the README's section between <!-- paper:begin --> and <!-- paper:end --> with "
        "the tables of RESULTS/REPORT.md (generated from its JSON files) and links to its figures, and the "
        "section between <!-- tasks:begin --> and <!-- tasks:end --> with the table of TASKS/tasks.json (and "
        "<!-- active:begin --> ... <!-- active:end --> with ACTIVE/active.json), so "
        "the README never holds a hand-typed number. Run it after `eval paper --out results/paper` and "
        "`eval tasks --out results/tasks`.",
    )
    er.add_argument("--results", type=Path, default=Path("results/paper"), help="a finished eval paper folder (default results/paper)")
    er.add_argument("--tasks", type=Path, default=Path("results/tasks"),
                    help="a finished eval tasks folder (default results/tasks; skipped when it has no tasks.json)")
    er.add_argument("--active", type=Path, default=Path("results/active"),
                    help="a finished eval active folder (default results/active; skipped when it has no active.json)")
    er.add_argument("--readme", type=Path, default=Path("README.md"), help="the README to update (default README.md)")
    er.set_defaults(func=cmd_eval_readme)


def cmd_eval_readme(args) -> int:
    from acoustic_sim.experiments.report import update_readme

    if not (args.results / "localization.json").is_file():
        raise ConfigError(f"{args.results}: no finished eval paper run there (localization.json is missing)")
    if not args.readme.is_file():
        raise ConfigError(f"{args.readme}: no such file")
    changed = update_readme(args.readme, args.results, image_prefix=args.results.as_posix())
    print(f"{args.readme}: {'updated from' if changed else 'already matches'} {args.results}")
    if (args.active / "active.json").is_file():
        from acoustic_sim.experiments import active

        changed = active.update_readme(args.readme, args.active, image_prefix=args.active.as_posix())
        print(f"{args.readme}: {'updated from' if changed else 'already matches'} {args.active}")
    if (args.tasks / "tasks.json").is_file():
        from apps import eval_tasks as tasks

        changed = tasks.update_readme(args.readme, args.tasks, image_prefix=args.tasks.as_posix())
        print(f"{args.readme}: {'updated from' if changed else 'already matches'} {args.tasks}")
    return 0


def cmd_eval_tasks(args) -> int:
    from apps.eval_tasks import run_tasks, table

    if args.episodes is not None and args.episodes < 1:
        raise ConfigError(f"--episodes must be >= 1, got {args.episodes}")
    if args.seed < 0:
        raise ConfigError(f"--seed must be >= 0, got {args.seed}")
    check_writable_folder(args.out, what="--out")
    run_tasks(out=args.out, profile=args.profile, episodes=args.episodes, seed=args.seed, quick=args.quick,
              policies=args.policies)
    print(table(args.out))
    print(f"wrote {args.out / 'tasks.json'}, {args.out / 'REPORT.md'}, {args.out / 'tasks.png'} and one episodes.json "
          "per task and policy")
    return 0


def cmd_eval_active(args) -> int:
    from acoustic_sim.experiments import active

    kwargs = {}
    if args.horizontal is not None:
        kwargs["n_horizontal"] = args.horizontal
    if args.off_plane is not None:
        kwargs["n_off_plane"] = args.off_plane
    if args.rooms:
        kwargs["rooms"] = tuple(args.rooms)
    if args.sounds:
        kwargs["sound_names"] = tuple(args.sounds)
    if args.pairs is not None:
        kwargs["pairs"] = args.pairs
    if args.precedence is not None:
        kwargs["precedence"] = None if args.precedence == "none" else args.precedence
    summary = active.run_active(out=args.out, hrtf=args.hrtf, profile=args.profile, seed=args.seed, quick=args.quick,
                                **kwargs)
    print(active.table(summary))
    if summary.get("pairs"):
        print(active.pairs_table(summary))
    print(f"wrote {args.out / 'active.json'}, {args.out / 'trials.json'}, pairs.json, {args.out / 'REPORT.md'} and "
          f"{args.out / 'active_confusion.png'}")
    return 0


def cmd_eval_paper(args) -> int:
    from acoustic_sim.experiments.paper import run_paper

    summary = run_paper(out=args.out, hrtf=args.hrtf, quick=args.quick, seed=args.seed)
    print(json.dumps(summary, indent=2))
    return 0
