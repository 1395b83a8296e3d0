"""Reliability: SIGKILL of a Ray worker or of the driver mid-sweep; initial-condition shards equal local runs."""

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import psutil
import pytest

from rovermarl.runner.job import run_job
from tests.conftest import ROOT, make_cfg


def _arrays(job_dir):
    """Every array of every finished run of a job: {(seed dir, file, key): array}."""
    out = {}
    for path in sorted(job_dir.glob("runs/seed_*/*.np[yz]")):
        if path.suffix == ".npy":
            out[(path.parent.name, path.name, "")] = np.load(path)
        else:
            with np.load(path) as z:
                out.update({(path.parent.name, path.name, k): z[k] for k in z.files})
    return out


def _assert_same(a, b):
    assert a.keys() == b.keys() and a
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=str(key))


@pytest.mark.parametrize("fresh", ["false", "true"])
def test_ic_shards_equal_local_evaluation(ray_session, tmp_path, fresh):
    over = ["setup=duo", "k=adaptive", "generations=60", "seeds=2", "parallel.chunk=25", f"evaluation.fresh_ic={fresh}"]
    run_job(make_cfg(*over, "parallel=serial"), tmp_path / "local")
    run_job(make_cfg(*over, "parallel.ic_shards=2"), tmp_path / "shards")
    _assert_same(_arrays(tmp_path / "local"), _arrays(tmp_path / "shards"))


def test_float32_runs_are_identical_serial_on_ray_and_over_ic_shards(ray_session, tmp_path):
    """env.dtype=float32 is close to float64, not equal to it, but a float32 run is one number wherever it runs."""
    over = ["setup=duo", "k=adaptive", "generations=60", "seeds=2", "parallel.chunk=25", "env.dtype=float32"]
    run_job(make_cfg(*over, "parallel=serial"), tmp_path / "serial")
    run_job(make_cfg(*over), tmp_path / "ray")
    run_job(make_cfg(*over, "parallel.ic_shards=2"), tmp_path / "shards")
    serial = _arrays(tmp_path / "serial")
    _assert_same(serial, _arrays(tmp_path / "ray"))
    _assert_same(serial, _arrays(tmp_path / "shards"))
    run_job(make_cfg(*over[:-1], "parallel=serial"), tmp_path / "float64")
    float64 = _arrays(tmp_path / "float64")                      # the same scores here, other trajectories
    assert all(not np.array_equal(serial[key], float64[key]) for key in serial if key[1:] == ("behaviour.npz", "xy"))


def _kill_one_running_task(killed: list, stop: threading.Event):
    """SIGKILL the first worker of this session's Ray (a descendant of this process, never another Ray on the
    machine) seen executing a chunk."""
    me = psutil.Process()
    while not stop.is_set() and not killed:
        for p in me.children(recursive=True):
            with contextlib.suppress(psutil.Error):
                if " ".join(p.cmdline()).startswith("ray::ChunkWorker.advance"):
                    os.kill(p.pid, signal.SIGKILL)
                    killed.append(p.pid)
                    return
        time.sleep(0.05)


def test_worker_sigkill_mid_run_is_retried_with_identical_results(ray_session, tmp_path):
    over = ["setup=duo", "k=2", "generations=1500", "seeds=3", "parallel.chunk=500", "record=off"]
    killed, stop = [], threading.Event()
    killer = threading.Thread(target=_kill_one_running_task, args=(killed, stop))
    killer.start()
    try:
        run_job(make_cfg(*over, "parallel=ray"), tmp_path / "ray")
    finally:
        stop.set()
        killer.join()
    assert killed, "no worker was killed: the test did not test anything"
    assert not psutil.pid_exists(killed[0]) or psutil.Process(killed[0]).status() == psutil.STATUS_ZOMBIE
    run_job(make_cfg(*over, "parallel=serial"), tmp_path / "serial")
    _assert_same(_arrays(tmp_path / "serial"), _arrays(tmp_path / "ray"))


@pytest.mark.slow
def test_driver_sigkill_mid_sweep_then_relaunch_resumes(tmp_path):
    sweep = tmp_path / "sweep"
    argv = [sys.executable, "-m", "rovermarl.train", "-m", "k=1,2", "setup=duo", "generations=2000", "seeds=4",
            "parallel.chunk=100", "checkpoint.every=100", "parallel.workers=1", f"hydra.sweep.dir={sweep}",
            "hydra.callbacks={}"]
    driver = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    deadline = time.time() + 240
    while time.time() < deadline and driver.poll() is None:
        if len(list(sweep.glob("*/runs/*/run.json"))) >= 2 and list(sweep.glob("*/runs/*/checkpoint.bin")):
            break
        time.sleep(0.05)
    assert driver.poll() is None, "the sweep ended before it could be killed"
    os.killpg(driver.pid, signal.SIGKILL)
    driver.wait()
    done = sorted(p.parent for p in sweep.glob("*/runs/*/run.json"))
    assert 2 <= len(done) < 8
    mtimes = {p: p.stat().st_mtime_ns for d in done for p in d.iterdir()}

    proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    log = proc.stdout + proc.stderr
    assert "resumes at generation" in log and "already finished, skipped" in log
    assert {p: p.stat().st_mtime_ns for p in mtimes} == mtimes             # finished runs untouched
    assert len(list(sweep.glob("*/runs/*/run.json"))) == 8 and not list(sweep.glob("*/runs/*/checkpoint*"))

    for k in (1, 2):
        job = f"generations=2000,k={k},setup=duo"
        run_job(make_cfg("setup=duo", f"k={k}", "generations=2000", "seeds=4", "parallel=serial"),
                tmp_path / "ref" / job)
        _assert_same(_arrays(tmp_path / "ref" / job), _arrays(sweep / job))
