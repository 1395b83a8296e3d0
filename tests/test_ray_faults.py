"""A Ray that dies under a sweep: the driver stops in one line naming the cause and how to resume, instead of
waiting or dumping Ray's logs; no Ray process of that driver is left. Only the launched driver's own processes
are touched (never another Ray on the machine)."""

import os
import re
import signal
import subprocess
import sys
import time

import psutil
import pytest

from tests.conftest import ROOT

# A line of Ray's C++ core: "[2026-12-01 22:25:49,504 E 4139 4282] task_manager.cc:1545: ..."
RAY_CORE_LINE = re.compile(r"^\[[-0-9: ,]+ [DIWEF] \d+ \d+\] ")


def _descendants(pid: int) -> list[psutil.Process]:
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _launched(tmp_path, *overrides: str) -> subprocess.Popen:
    """A duo sweep of 2 seeds on an embedded Ray (its own session), once its first run's dir exists."""
    argv = [sys.executable, "-m", "rovermarl.train", "-m", "setup=duo", "seeds=2", "record=off", "ray.num_cpus=2",
            *overrides, "~hydra.callbacks.plot", f"hydra.sweep.dir={tmp_path / 'sweep'}"]
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + 240
    while not list(tmp_path.glob("sweep/*/runs/*")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    return proc


@pytest.mark.slow
@pytest.mark.parametrize("victim", ["gcs_server", "raylet"])
def test_a_dead_ray_stops_the_driver_in_one_line(tmp_path, victim):
    proc = _launched(tmp_path, "k=1,2", "generations=200000", "parallel.chunk=500", "parallel.stall_timeout=20")
    time.sleep(2)
    started = _descendants(proc.pid)                                   # this driver's Ray, and only it
    targets = [p for p in started if victim in p.name()]
    assert targets, f"no {victim} of this driver found"
    for p in targets:
        p.kill()
    try:
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode not in (0, None)
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err and len(lines) <= 3, err[-3000:]
    assert not [line for line in lines if RAY_CORE_LINE.match(line)], err[-3000:]   # RAY_BACKEND_LOG_LEVEL=fatal
    assert lines[-1].startswith("rovermarl.train: error: ") and "relaunch the same command to resume" in lines[-1]
    _, left = psutil.wait_procs(started, timeout=10)
    assert not left, [(p.pid, p.name()) for p in left]


@pytest.mark.slow
def test_a_launch_stopped_and_continued_does_not_count_the_stop_as_a_stall(tmp_path):
    """Ctrl-Z and ``fg``, or a scheduler's suspend and resume (SIGSTOP, SIGCONT), of the driver and its Ray for longer
    than ``parallel.stall_timeout``: the launch goes on and finishes (it stopped at once, 'no chunk finished', unless
    a chunk ended in the first half second after the stop: a chunk here takes about 2.5 s)."""
    proc = _launched(tmp_path, "k=1", "generations=120000", "parallel.chunk=30000", "parallel.stall_timeout=10")
    time.sleep(1)
    assert proc.poll() is None, proc.communicate()[1][-3000:]
    group = [psutil.Process(proc.pid), *_descendants(proc.pid)]        # the driver and its Ray
    try:
        for p in group:
            p.suspend()
        time.sleep(15)                                                 # past the 10 s stall timeout
        for p in group:
            p.resume()
        _, err = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, err[-3000:]
    assert len(list(tmp_path.glob("sweep/*/summary.json"))) == 1
