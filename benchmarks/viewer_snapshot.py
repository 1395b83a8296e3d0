"""Screenshot of a recording in the Rerun web viewer, taken by headless Chromium (not part of CI).

Serves ``RRD`` with ``rerun --web-viewer`` (on 127.0.0.1, free ports), opens it in headless Chromium (software
WebGL through ANGLE's SwiftShader), waits until the viewer has loaded and drawn the recording (two screenshots in a
row show the same views) and saves a PNG of the page:

    python benchmarks/viewer_snapshot.py runs/seed_000/run.rrd docs/figures/viewer_solo.png [--wait 35]

Needs ``chromium`` (``apt-get install -y chromium``) and ``websocket-client`` (``pip install websocket-client``).
Measured on a 2-core machine without a GPU: the WebGL viewer needs 35 s to a few minutes of real time (it draws
every frame in software while the data streams in) before it has drawn all of a 5000-generation run; Chromium's
``--virtual-time-budget`` does not advance WebGL, so the script really waits (through the DevTools protocol), and
``--use-gl=swiftshader`` stalls on "Loading Application Bundle".
Both processes are stopped on exit, also on errors.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

TOP_BAR = 40                               # px: the viewer's top bar (its latency counter keeps changing)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(url: str, seconds: float) -> bytes:
    """GET ``url`` until it answers (``seconds`` at most)."""
    deadline = time.monotonic() + seconds
    while True:
        try:
            with urllib.request.urlopen(url, timeout=2) as r:
                return r.read()
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.25)


@contextlib.contextmanager
def started(cmd: list[str], log: Path):
    """Run ``cmd`` in its own process group for the duration of the block; stop the whole group after."""
    with open(log, "w") as f:
        proc = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


class DevTools:
    """The smallest DevTools-protocol client: one page target over a websocket."""

    def __init__(self, ws_url: str):
        import websocket  # websocket-client

        self.ws = websocket.create_connection(ws_url, timeout=120, suppress_origin=True)
        self.next_id = 0

    def call(self, method: str, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def close(self) -> None:
        self.ws.close()


def screenshot(dt: DevTools) -> bytes:
    return base64.b64decode(dt.call("Page.captureScreenshot", format="png")["data"])


def settle(dt: DevTools, wait: float, max_wait: float, every: float) -> bytes:
    """The page once it stops changing: after ``wait`` s, a screenshot every ``every`` s until two in a row show
    the same views (the top bar, whose latency counter ticks, is left out), ``max_wait`` s at most."""
    from io import BytesIO

    from PIL import Image

    def views(png: bytes) -> bytes:
        im = Image.open(BytesIO(png))
        return im.crop((0, TOP_BAR, im.width, im.height)).tobytes()

    t0 = time.monotonic()
    time.sleep(wait)                       # real time: the WebGL viewer loads and draws in software
    png = screenshot(dt)
    while time.monotonic() - t0 < max_wait:
        time.sleep(every)
        again = screenshot(dt)
        if views(again) == views(png):
            print(f"viewer settled after {time.monotonic() - t0:.0f} s", file=sys.stderr)
            return again
        png = again
    print(f"viewer still changing after {max_wait:.0f} s; keeping the last screenshot", file=sys.stderr)
    return png


def snapshot(rrd: Path, out: Path, width: int = 1600, height: int = 1000, wait: float = 35.0,
             chromium: str = "chromium", max_wait: float = 300.0, every: float = 10.0) -> Path:
    exe = shutil.which(rerun := "rerun") or str(Path(sys.executable).with_name(rerun))
    web, grpc, debug = free_port(), free_port(), free_port()
    url = (f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}%2Fproxy&renderer=webgl")
    with tempfile.TemporaryDirectory(prefix="viewer_snapshot_") as tmp:
        tmp = Path(tmp)
        serve = [exe, "--web-viewer", "--bind", "127.0.0.1", "--web-viewer-port", str(web), "--port", str(grpc),
                 str(rrd)]
        browser = [chromium, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                   "--hide-scrollbars", "--mute-audio", "--no-first-run", f"--user-data-dir={tmp / 'profile'}",
                   f"--remote-debugging-port={debug}", f"--window-size={width},{height}", "about:blank"]
        with started(serve, tmp / "rerun.log"), started(browser, tmp / "chromium.log"):
            wait_for(f"http://127.0.0.1:{web}/", 30)
            targets = json.loads(wait_for(f"http://127.0.0.1:{debug}/json", 30))
            page = next(t for t in targets if t.get("type") == "page")
            dt = DevTools(page["webSocketDebuggerUrl"])
            try:
                dt.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1,
                        mobile=False)
                dt.call("Page.enable")
                dt.call("Page.navigate", url=url)
                png = settle(dt, wait, max_wait, every)
            finally:
                dt.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(png)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("rrd", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--width", type=int, default=1600)
    p.add_argument("--height", type=int, default=1000)
    p.add_argument("--wait", type=float, default=35.0, help="seconds of real time before the first screenshot")
    p.add_argument("--max-wait", type=float, default=300.0, help="give up waiting for a still page after this")
    p.add_argument("--every", type=float, default=10.0, help="seconds between screenshots compared")
    p.add_argument("--chromium", default="chromium")
    a = p.parse_args()
    if not a.rrd.is_file():
        sys.exit(f"viewer_snapshot: {a.rrd}: no such file")
    if shutil.which(a.chromium) is None:
        sys.exit(f"viewer_snapshot: no {a.chromium} on PATH (apt-get install -y chromium)")
    print(snapshot(a.rrd, a.out, a.width, a.height, a.wait, a.chromium, a.max_wait, a.every))


if __name__ == "__main__":
    main()
