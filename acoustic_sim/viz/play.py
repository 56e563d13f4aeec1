"""``acoustic-sim play FILE.rrd``: open a recording in the rerun viewer, or say how to.

The viewer is the ``rerun`` executable that ships with ``rerun-sdk`` (run as
``python -m rerun`` so that it is the same version as the recordings). Without a display
(no ``DISPLAY``/``WAYLAND_DISPLAY`` on Linux) a window cannot open; ``play`` then prints the
two ways to look at the file: copy it to a machine with a display, or serve rerun's web
viewer from here and open it in a browser.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

import rerun as rr

from acoustic_sim.viz.recorder import RecordingError

WEB_PORT = 9090
GRPC_PORT = 9876


def has_display() -> bool:
    """Whether a native viewer window can open here."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_recording(path) -> Path:
    """Return ``path`` as a Path if it is a readable rerun recording, else raise RecordingError."""
    p = Path(path)
    if p.suffix.lower() != ".rrd":
        raise RecordingError(f"{str(p)!r} is not a rerun recording: expected a file ending in .rrd")
    if not p.exists():
        raise RecordingError(f"recording {str(p)!r} does not exist")
    if not p.is_file():
        raise RecordingError(f"recording {str(p)!r} is not a file")
    try:
        with open(p, "rb") as f:
            magic = f.read(4)
    except OSError as err:
        raise RecordingError(f"cannot read recording {str(p)!r}: {err.strerror or err}") from err
    if not magic.startswith(b"RR"):
        raise RecordingError(f"{str(p)!r} is not a rerun recording (no RRD header); was it written by rerun?")
    try:
        recordings = rr.chunk.RrdReader(p).recordings()
    except Exception as err:  # rerun raises its own types for corrupt or truncated files
        raise RecordingError(f"{str(p)!r} cannot be read as a rerun recording: {err}") from err
    if not recordings:
        raise RecordingError(f"{str(p)!r} holds no recording (only a blueprint?)")
    return p


def viewer_command(path, *, web: bool = False) -> list[str]:
    """The command that opens ``path`` in rerun's native viewer, or serves its web viewer."""
    cmd = [sys.executable, "-m", "rerun", str(path)]
    if web:
        cmd += ["--web-viewer", "--web-viewer-port", str(WEB_PORT), "--port", str(GRPC_PORT)]
    return cmd


def how_to_view(path) -> str:
    """Plain instructions for viewing ``path`` where no window can open."""
    q = shlex.quote(str(path))
    return (
        f"No display here (DISPLAY and WAYLAND_DISPLAY are unset), so the rerun viewer cannot open a window.\n"
        f"To view {path}:\n"
        f"  * on a machine with a display and rerun-sdk=={rr.__version__}: rerun {q}\n"
        f"  * in a browser, serving rerun's web viewer from this machine:\n"
        f"        acoustic-sim play {q} --web      (same as: rerun --web-viewer {q})\n"
        f"    then open http://localhost:{WEB_PORT}/?url=rerun%2Bhttp%3A%2F%2Flocalhost%3A{GRPC_PORT}%2Fproxy\n"
        f"    (from another machine: ssh -L {WEB_PORT}:localhost:{WEB_PORT} -L {GRPC_PORT}:localhost:{GRPC_PORT} HOST)\n"
    )


def play(path, *, web: bool = False, out=None) -> int:
    """Open a recording: the native viewer if there is a display, rerun's web viewer if
    ``web``, else print how to view it. Returns a process exit status.

    Raises
    ------
    RecordingError
        If ``path`` is not an existing, readable ``.rrd`` recording.
    """
    out = out if out is not None else sys.stdout
    p = check_recording(path)
    if not web and not has_display():
        print(how_to_view(p), file=out, end="")
        return 0
    cmd = viewer_command(p, web=web)
    if web:
        print(f"Serving {p} to rerun's web viewer: open http://localhost:{WEB_PORT}/?url=rerun%2Bhttp%3A%2F%2Flocalhost%3A"
              f"{GRPC_PORT}%2Fproxy (Ctrl-C stops)", file=out, flush=True)
    try:
        rc = subprocess.call(cmd)
    except KeyboardInterrupt:
        return 130
    if rc != 0 and not web:
        print(f"the rerun viewer exited with status {rc}.\n" + how_to_view(p), file=out, end="")
    return rc
