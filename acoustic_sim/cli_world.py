"""``acoustic-sim`` subcommands of the MuJoCo world (``snapshot``); ``cli.build_parser`` calls
:func:`add_parsers`. MuJoCo is imported inside the commands: ``snapshot`` must choose the
OpenGL backend (MUJOCO_GL) before MuJoCo is first imported."""

from __future__ import annotations

import json
from pathlib import Path


def add_parsers(sub) -> None:
    s = sub.add_parser(
        "snapshot",
        help="render a picture of a MuJoCo scene to PNG",
        description="Renders a composed scene from a fixed camera with MuJoCo's offscreen renderer and writes a PNG: "
        "cabin (the robot in the driver's seat, hands on the gear knob and the brake handle) or room (the robot on "
        "its wheelchair, a person and a loudspeaker). Uses EGL where available, else OSMesa; set MUJOCO_GL to choose.",
    )
    s.add_argument("--scene", choices=("cabin", "room"), required=True, help="which scene to draw")
    s.add_argument("--out", type=Path, required=True, help="output .png path")
    s.add_argument("--width", type=int, default=1280, help="image width in pixels, 16-4096 (default 1280)")
    s.add_argument("--height", type=int, default=800, help="image height in pixels, 16-4096 (default 800)")
    s.set_defaults(func=cmd_snapshot)

    pl = sub.add_parser(
        "play",
        help="open a rerun recording in the viewer",
        description="Opens FILE.rrd in rerun's viewer; without a display, prints how to view it (or use --web to "
        "serve rerun's web viewer).",
    )
    pl.add_argument("file", type=Path, help="a recording, e.g. runs/demo.rrd")
    pl.add_argument("--web", action="store_true", help="serve rerun's web viewer on http://localhost:9090 instead")
    pl.set_defaults(func=cmd_play)


def cmd_snapshot(args) -> int:
    from acoustic_sim.world.snapshot import snapshot

    out = snapshot(args.scene, args.out, width=args.width, height=args.height)
    print(json.dumps({"scene": args.scene, "out": str(out), "width": args.width, "height": args.height}))
    return 0


def cmd_play(args) -> int:
    from acoustic_sim.viz import play

    return play(args.file, web=args.web)
