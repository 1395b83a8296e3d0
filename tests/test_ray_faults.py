"""A Ray that dies under a sweep: the driver stops in one line naming the cause and how to resume, instead of
waiting or dumping Ray's logs; no Ray process of that driver is left."""

import os
import signal
import subprocess
import sys
import time

import psutil
import pytest

from tests.conftest import ROOT


def _ray_procs() -> dict[int, str]:
    out = {}
    for p in psutil.process_iter(["pid", "cmdline"]):
        cmd = " ".join(p.info["cmdline"] or [])
        if "gcs_server" in cmd or "raylet" in cmd or "ray::" in cmd or "ray/_private" in cmd or "dashboard" in cmd:
            out[p.info["pid"]] = cmd
    return out


@pytest.mark.parametrize("victim", ["gcs_server", "raylet"])
def test_a_dead_ray_stops_the_driver_in_one_line(tmp_path, victim):
    before = set(_ray_procs())
    argv = [sys.executable, "-m", "rovermarl.train", "-m", "k=1,2", "setup=duo", "generations=200000", "seeds=2",
            "parallel.chunk=500", "record=off", "ray.num_cpus=2", "parallel.stall_timeout=20",
            "~hydra.callbacks.plot", f"hydra.sweep.dir={tmp_path / 'sweep'}"]
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 240
    while not list(tmp_path.glob("sweep/*/runs/*")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(2)
    targets = [pid for pid, cmd in _ray_procs().items() if pid not in before and victim in cmd.split()[0]]
    assert targets, f"no {victim} of this driver found"
    for pid in targets:
        os.kill(pid, signal.SIGKILL)
    try:
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode not in (0, None)
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err and len(lines) <= 3, err[-3000:]
    assert lines[-1].startswith("rovermarl.train: error: ") and "relaunch the same command to resume" in lines[-1]
    time.sleep(5)
    left = {pid: cmd for pid, cmd in _ray_procs().items() if pid not in before}
    assert not left, left
