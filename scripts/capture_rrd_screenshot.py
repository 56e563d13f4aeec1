"""Capture a picture of a rerun recording as the viewer shows it (for the README).

How: serve the recording with rerun's own web viewer (``python -m rerun --serve-web FILE``,
the viewer of the installed rerun-sdk), open it in headless Chromium (WebGL through
SwiftShader, so no GPU or display is needed), wait until the viewer has loaded the recording
and its picture has stopped changing, and save a screenshot through the Chrome DevTools
protocol (``websockets``). The recording opens with its default blueprint, with the time
cursor where the viewer puts it (the end of the recording).

Needs Chromium (Debian: ``apt-get install chromium``; or pass ``--chromium PATH``).

    python scripts/capture_rrd_screenshot.py runs/demo.rrd --out docs/recording.png
    python scripts/capture_rrd_screenshot.py --sample --out docs/recording.png   # a synthetic cabin episode

Exit status: 0 on success, 2 with a one-line reason otherwise.
"""

from __future__ import annotations

import argparse
import base64
import functools
import http.server
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
import urllib.request
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_http(url: str, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            with urllib.request.urlopen(url, timeout=2):
                return
        except OSError:
            time.sleep(0.3)
    raise RuntimeError(f"{url} did not answer within {timeout:.0f} s")


def _find_chromium(explicit: str | None) -> str:
    for name in ([explicit] if explicit else []) + ["chromium", "chromium-browser", "google-chrome", "chrome", "chromium-headless-shell"]:
        path = shutil.which(name) if name else None
        if path:
            return path
    raise RuntimeError("no Chromium found: install it (Debian: apt-get install chromium) or pass --chromium PATH")


class _Page:
    """The smallest Chrome DevTools client that can navigate and take screenshots."""

    def __init__(self, ws) -> None:
        self.ws = ws
        self.next_id = 0

    def call(self, method: str, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=180))
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])



def _signature(png: bytes):
    """A small grey thumbnail without the top bar (whose latency read-out keeps changing)."""
    import io

    import numpy as np
    from PIL import Image

    im = Image.open(io.BytesIO(png)).convert("L")
    w, h = im.size
    return np.asarray(im.crop((0, 40, w, h)).resize((160, 80)), dtype=np.int16)


class _CorsHandler(http.server.SimpleHTTPRequestHandler):
    def end_headers(self) -> None:
        self.send_header("Access-Control-Allow-Origin", "*")
        super().end_headers()

    def log_message(self, *args) -> None:  # quiet
        pass


def _serve_file(path: Path) -> tuple[http.server.ThreadingHTTPServer, str]:
    """Serve ``path`` over HTTP (with CORS, for the viewer on another port); returns its URL."""
    handler = functools.partial(_CorsHandler, directory=str(path.parent))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}/{urllib.parse.quote(path.name)}"


def _stop(proc: subprocess.Popen | None) -> None:
    """Stop a process started in its own session, and everything it started."""
    if proc is None or proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(10)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _wait_until_settled(page: _Page, *, timeout: float, settle: float, min_wait: float) -> tuple[bytes, bool]:
    """Screenshots until the picture has not changed for ``settle`` seconds."""
    start = time.monotonic()
    last, stable_since, png = None, None, b""
    while time.monotonic() - start < timeout:
        time.sleep(1.0)
        png = page.screenshot()
        sig = _signature(png)
        if last is None or sig.shape != last.shape or np.mean(np.abs(sig - last) > 8) > 0.002:
            last, stable_since = sig, time.monotonic()
        elif time.monotonic() - stable_since >= settle and time.monotonic() - start > min_wait and np.std(sig) > 10:
            return png, True
    return png, False


def capture(rrd: Path, out: Path, *, width: int = 1600, height: int = 900, timeout: float = 600.0,
            settle: float = 8.0, chromium: str | None = None, verbose: bool = True) -> Path:
    """Open ``rrd`` in rerun's web viewer in headless Chromium and save a PNG of it to ``out``.

    The recording is fetched over HTTP by the viewer while the page is small (rendering with
    SwiftShader is slow, and the viewer ingests data between frames), until the picture stops
    changing: the default blueprint follows the newest data, so loading is done when the time
    cursor stops. Then the page is enlarged to ``width`` x ``height`` and captured once the
    picture has settled again.
    """
    rrd = Path(rrd).resolve()
    if not rrd.is_file() or rrd.suffix != ".rrd":
        raise RuntimeError(f"{rrd} is not an .rrd file")
    browser = _find_chromium(chromium)
    web_port, grpc_port = _free_port(), _free_port()
    env = dict(os.environ, BROWSER="true")  # never let rerun open a browser itself
    # The web viewer's assets from the installed rerun-sdk (so viewer and file versions match).
    server = subprocess.Popen(
        [sys.executable, "-m", "rerun", "--serve-web", "--web-viewer-port", str(web_port), "--port", str(grpc_port),
         "--bind", "127.0.0.1"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True)
    files, file_url = _serve_file(rrd)
    profile = tempfile.mkdtemp(prefix="rrd-shot-")
    chrome = None
    try:
        _wait_http(f"http://127.0.0.1:{web_port}/", 60)
        chrome = subprocess.Popen(
            [browser, "--headless=new", "--no-sandbox", "--no-first-run", "--no-default-browser-check",
             "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--enable-webgl", "--ignore-gpu-blocklist",
             f"--window-size={width},{height}", "--hide-scrollbars", "--remote-debugging-port=0",
             f"--user-data-dir={profile}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
        ws_url = None
        end = time.monotonic() + 60
        while ws_url is None and time.monotonic() < end:
            line = chrome.stderr.readline()
            if not line and chrome.poll() is not None:
                raise RuntimeError(f"Chromium exited with status {chrome.returncode} before DevTools started")
            m = re.search(r"DevTools listening on (ws://\S+)", line)
            if m:
                ws_url = m.group(1)
        if ws_url is None:
            raise RuntimeError("Chromium did not start DevTools within 60 s")
        port = urllib.parse.urlparse(ws_url).port
        targets = json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10).read())
        page_ws = next(t["webSocketDebuggerUrl"] for t in targets if t.get("type") == "page")
        from websockets.sync.client import connect

        with connect(page_ws, max_size=None, open_timeout=20) as ws:
            page = _Page(ws)
            page.call("Emulation.setDeviceMetricsOverride", width=480, height=270, deviceScaleFactor=1, mobile=False)
            url = f"http://127.0.0.1:{web_port}/?url={urllib.parse.quote(file_url, safe='')}"
            if verbose:
                print(f"loading {url}", file=sys.stderr)
            t0 = time.monotonic()
            page.call("Page.navigate", url=url)
            _png, loaded = _wait_until_settled(page, timeout=timeout, settle=settle, min_wait=20)
            if verbose:
                print(f"{'loaded' if loaded else 'still loading, going on'} after {time.monotonic() - t0:.0f} s", file=sys.stderr)
            page.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1, mobile=False)
            png, settled = _wait_until_settled(page, timeout=max(120.0, timeout / 3), settle=settle / 2, min_wait=5)
            if verbose and not settled:
                print("the full-size picture did not settle; saving the last one", file=sys.stderr)
        out = Path(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_bytes(png)
        return out
    finally:
        _stop(chrome)
        _stop(server)
        files.shutdown()
        shutil.rmtree(profile, ignore_errors=True)


def _sample_recording(path: Path, seconds: float) -> Path:
    from acoustic_sim.world.snapshot import choose_gl_backend

    choose_gl_backend()
    from acoustic_sim.acoustics.hrtf import HRTF
    from acoustic_sim.directions import DirectionGrid
    from acoustic_sim.frames import FRAME_RATE
    from acoustic_sim.viz.recorder import Recorder
    from acoustic_sim.viz.sample import SyntheticEpisode, scene_model

    model, _ = scene_model("cabin")
    grid = DirectionGrid.paper(HRTF.load("kemar")).vectors
    episode = SyntheticEpisode(model, grid, seed=0)
    with Recorder.open(path, model, grid) as rec:
        for k in range(int(seconds * FRAME_RATE)):
            rec.log_frame((k + 1) / FRAME_RATE, k, **episode.frame(k))
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rrd", nargs="?", type=Path, help="recording to picture (e.g. runs/demo.rrd)")
    ap.add_argument("--sample", action="store_true", help="record a synthetic cabin episode first and picture that")
    ap.add_argument("--seconds", type=float, default=6.0, help="length of the --sample episode (s)")
    ap.add_argument("--out", type=Path, default=Path("docs/recording.png"), help="PNG to write")
    ap.add_argument("--size", default="1600x900", help="viewport WIDTHxHEIGHT in pixels")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds to wait for the viewer")
    ap.add_argument("--chromium", help="path of the Chromium executable")
    args = ap.parse_args(argv)
    try:
        if args.sample:
            tmp = Path(tempfile.mkdtemp()) / "sample.rrd"
            rrd = _sample_recording(tmp, args.seconds)
        elif args.rrd is not None:
            rrd = args.rrd
        else:
            ap.error("give a recording or --sample")
        w, h = (int(v) for v in args.size.lower().split("x"))
        out = capture(rrd, args.out, width=w, height=h, timeout=args.timeout, chromium=args.chromium)
    except (RuntimeError, OSError, ImportError, ValueError) as err:
        print(f"capture_rrd_screenshot: error: {err}", file=sys.stderr)
        return 2
    print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
