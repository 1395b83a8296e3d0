"""One writer per output dir: a second launch on a sweep (or job) dir that another launch holds stops at once in
one line naming the holder, and computes nothing; the first completes with every recording verifying."""

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rovermarl.record import lock
from rovermarl.runner.job import run_job
from tests.conftest import ROOT, assert_same_curves, make_cfg, run_cli, sweep_curves

ARGS = ("-m", "k=1,2", "setup=duo", "generations=6000", "seeds=2", "parallel=serial", "parallel.chunk=500",
        "checkpoint.every=500", "~hydra.callbacks.plot")   # long enough that the first is still running (compiled loop)


def test_two_launches_on_one_sweep_dir_one_refuses_the_sweep_completes(tmp_path):
    sweep = tmp_path / "sweep"
    argv = [sys.executable, "-m", "rovermarl.train", *ARGS, f"hydra.sweep.dir={sweep}"]
    first = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list(sweep.glob("*/runs/*/checkpoint.bin")) and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert first.poll() is None, "the first launch ended before the second started"
    second = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert second.returncode == 75
    lines = second.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"rovermarl.train: error: {sweep} is in use by PID {first.pid} "
                                                   f"on {socket.gethostname()} since ")
    _, err = first.communicate(timeout=300)
    assert first.returncode == 0, err[-3000:]
    jobs = sorted(p for p in sweep.iterdir() if (p / "summary.json").is_file())
    assert len(jobs) == 2
    for job in jobs:                                   # computed once: one launch logged, no leftover temp files
        assert len((job / "invocations.jsonl").read_text().splitlines()) == 1
        assert not [p for p in job.rglob("*") if p.name.startswith(".") and p.name != ".lock" and p.is_file()
                    and p.parent.name != ".hydra"]
    rerun = str(Path(sys.executable).with_name("rerun"))             # the venv's rerun CLI
    for rrd in sorted(sweep.glob("*/runs/*/run.rrd")):
        verify = subprocess.run([rerun, "rrd", "verify", str(rrd)], capture_output=True, text=True, timeout=120)
        assert verify.returncode == 0, verify.stderr[-2000:]
    ref = run_cli(*ARGS, f"hydra.sweep.dir={tmp_path / 'ref'}")          # the same sweep, alone
    assert ref.returncode == 0, ref.stderr[-2000:]
    assert_same_curves(sweep_curves(sweep), sweep_curves(tmp_path / "ref"))


def test_a_held_job_dir_refuses_another_writer_and_is_free_after(tmp_path):
    job = tmp_path / "job"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from rovermarl.record import lock\n"
                               f"with lock.hold({str(job)!r}):\n    print('held', flush=True); time.sleep(60)"],
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    cfg = make_cfg("generations=5", "seeds=1", "parallel=serial", "record=off")
    with pytest.raises(lock.Locked, match=f"^{job} is in use by PID {holder.pid} on "):
        run_job(cfg, job)
    holder.kill()
    holder.wait()
    assert run_job(cfg, job)["seeds"] == [0]           # a dead holder's lock is gone with its process


def test_a_launchs_lock_removes_the_temp_files_of_a_killed_launch_and_nothing_else(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()                 # a process that has ended: its PID runs nothing
    d = tmp_path / "sweep"
    (d / "figures").mkdir(parents=True)
    left = d / "figures" / f".curves_duo.pdf.{dead}.8004aad7.tmp"          # atomic_open's name for a temp file
    mine = d / f".summary.json.{os.getpid()}.0123abcd.tmp"                  # a running process's: kept
    other = d / "figures" / ".notes.tmp"                                    # not atomic_open's: kept
    for p in (left, mine, other):
        p.write_text("partial")
    with lock.hold(d):                                                      # a job's lock: cleans nothing
        assert left.exists()
    with lock.hold(d, clean=True):
        assert not left.exists() and mine.exists() and other.exists()
