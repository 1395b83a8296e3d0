"""SIGINT and SIGTERM at fixed delays over the first seconds of a default launch (``python -m rovermarl.train``):
each must end with exit 130 / 143, at most 3 lines on stderr and no traceback, leave no process of the launch
alive 5 s after it exits, and (``--relaunch``) its relaunch must give the curves of an uninterrupted launch.

    python benchmarks/signal_sweep.py [--start 0.5] [--stop 15] [--step 0.5] [--relaunch N] [ARG ...]

ARGs are extra train overrides. Prints one JSON object per launch, then a summary line (JSON) with ``"ok"``.
A launch's processes are told apart from any other by an environment marker they all inherit (Ray's too).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def marked(tag: str) -> list[int]:
    """PIDs of live processes whose environment carries ``SIGNAL_SWEEP=tag``."""
    out = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            env = Path(f"/proc/{pid}/environ").read_bytes()
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if f"SIGNAL_SWEEP={tag}".encode() in env.split(b"\0") and state != "Z":
            out.append(int(pid))
    return out


def launch(run_dir: Path, extra: list[str], tag: str) -> subprocess.Popen:
    # a job started from a non-interactive shell ignores SIGINT: give the child the default disposition
    code = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
            "os.execvp(sys.executable, [sys.executable, '-m', 'rovermarl.train', *sys.argv[1:]])")
    return subprocess.Popen([sys.executable, "-c", code, f"hydra.run.dir={run_dir}", *extra], cwd=ROOT,
                            env={**os.environ, "SIGNAL_SWEEP": tag}, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL,
                            text=True)


def curves(run_dir: Path) -> dict:
    out = {}
    for path in sorted(run_dir.glob("runs/seed_*/curve.npz")):
        with np.load(path) as z:
            out[path.parent.name] = {k: z[k] for k in z.files}
    return out


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(a[r].keys() == b[r].keys() and
                                        all(np.array_equal(a[r][k], b[r][k], equal_nan=True) for k in a[r])
                                        for r in a)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--start", type=float, default=0.5)
    p.add_argument("--stop", type=float, default=15.0)
    p.add_argument("--step", type=float, default=0.5)
    p.add_argument("--relaunch", type=int, default=0, help="relaunch every N-th interrupted launch (0: none)")
    args, extra = p.parse_known_args()
    work = Path(tempfile.mkdtemp(prefix="signal-sweep-"))
    ref = None
    if args.relaunch:
        tag = uuid.uuid4().hex
        proc = launch(work / "ref", extra, tag)
        proc.communicate()
        ref = curves(work / "ref")
    delays = np.arange(args.start, args.stop + 1e-9, args.step)
    failures, n = 0, 0
    for i, delay in enumerate(delays):
        for sig, code in ((signal.SIGTERM, 143), (signal.SIGINT, 130)):
            tag, run_dir = uuid.uuid4().hex, work / f"run_{i}_{sig}"
            proc = launch(run_dir, extra, tag)
            time.sleep(float(delay))
            sent = proc.poll() is None
            if sent:
                proc.send_signal(sig)
            t0 = time.monotonic()
            try:
                _, err = proc.communicate(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                _, err = proc.communicate()
            answered = time.monotonic() - t0
            time.sleep(5)
            left = marked(tag)
            lines = [x for x in err.splitlines() if x.strip()]
            ok = (not sent and proc.returncode == 0) or (proc.returncode == code and len(lines) <= 3 and
                                                          "Traceback" not in err and answered <= 5)
            ok = ok and not left
            row = {"delay_s": float(delay), "signal": signal.Signals(sig).name, "sent": sent,
                   "exit": proc.returncode, "answered_s": round(answered, 2), "lines": len(lines),
                   "last": lines[-1] if lines else "", "left": len(left)}
            if ref is not None and n % args.relaunch == 0:
                again = launch(run_dir, extra, uuid.uuid4().hex)
                again.communicate()
                row["relaunch_identical"] = again.returncode == 0 and same(curves(run_dir), ref)
                ok = ok and row["relaunch_identical"]
            row["ok"] = ok
            failures += not ok
            n += 1
            for pid in left:
                os.kill(pid, signal.SIGKILL)
            print(json.dumps(row), flush=True)
    print(json.dumps({"launches": n, "failures": failures, "ok": failures == 0, "dir": str(work)}), flush=True)
    sys.exit(0 if failures == 0 else 1)


if __name__ == "__main__":
    main()
