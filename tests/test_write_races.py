"""Writes that cannot leave their dir (issue 51), attacked as a second writer in a shared results dir would: a dir
swapped for a link while a launch writes (each race in a loop), a lock or Hydra file hard-linked to a file elsewhere,
a ``ray.address`` that accepts and then closes or stays silent. Nothing outside changes; each refusal is one line."""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from rovermarl.record import atomic, lock
from rovermarl.record.safe_read import Unsafe
from rovermarl.runner.job import run_job
from tests.conftest import ROOT, make_cfg, run_cli, study_module

ROUNDS = 30
JOB = "generations=30,k=1,setup=duo"
SWEEP = ("-m", "k=1", "setup=duo", "generations=30", "seeds=1", "parallel=serial")
ENV = {"PYTHONPATH": str(ROOT)}


def _victim(tmp_path: Path) -> Path:
    """A dir outside with files a write through a link would change, remove or add to."""
    victim = tmp_path / "outside"
    victim.mkdir(exist_ok=True)
    for name in ("precious", "run.json", "curve.npz", "summary.json", ".lock"):
        (victim / name).write_text(f"{name}: precious\n")
    return victim


def _snapshot(victim: Path) -> dict:
    return {p.relative_to(victim).as_posix(): p.read_bytes() for p in sorted(victim.rglob("*")) if p.is_file()}


class Swapper(threading.Thread):
    """Once ``trigger`` exists, swaps ``target`` (a dir) for a link to ``victim`` and back, again and again."""

    def __init__(self, target: Path, victim: Path, trigger: Path):
        super().__init__(daemon=True)
        self.target, self.victim, self.trigger = target, victim, trigger
        self.stop, self.swaps = threading.Event(), 0

    def run(self) -> None:
        aside = self.target.with_name(self.target.name + ".real")
        while not self.trigger.exists() and not self.stop.is_set():
            time.sleep(0.0005)
        while not self.stop.is_set():
            try:
                if self.target.is_symlink():                      # back to the real dir
                    os.unlink(self.target)
                if aside.exists():
                    shutil.rmtree(self.target, ignore_errors=True)   # a dir the writer made meanwhile
                    os.rename(aside, self.target)
                time.sleep(0.001)
                os.rename(self.target, aside)                     # then a link in its place
                try:
                    os.symlink(self.victim, self.target)
                except FileExistsError:
                    shutil.rmtree(self.target, ignore_errors=True)
                    os.symlink(self.victim, self.target)
                self.swaps += 1
                time.sleep(0.002)
            except OSError:
                time.sleep(0.001)

    def end(self) -> None:
        self.stop.set()
        self.join()
        aside = self.target.with_name(self.target.name + ".real")
        if self.target.is_symlink():
            self.target.unlink()
        if aside.is_dir() and not self.target.exists():
            aside.rename(self.target)


def _one_line(e: BaseException) -> str:
    text = str(e)
    assert "\n" not in text and text, text
    return text


@pytest.fixture(scope="module")
def cfg():
    return make_cfg("setup=duo", "generations=5", "seeds=1", "parallel=serial", "record=off",
                    "checkpoint.every=1", "parallel.chunk=1")


def test_a_run_dir_swapped_for_a_link_while_a_relaunch_writes_takes_no_file_outside(cfg, tmp_path):
    """issue 51: runs/seed_000 swapped for a link once the job's .lock appears; 5 of 5 wrote into the victim."""
    victim = _victim(tmp_path)
    before, refused = _snapshot(victim), []
    for i in range(ROUNDS):
        job = tmp_path / f"job{i}"
        (job / "runs" / "seed_000").mkdir(parents=True)
        swapper = Swapper(job / "runs" / "seed_000", victim, job / ".lock")
        swapper.start()
        try:
            run_job(cfg, job)
        except OSError as e:                     # Unsafe, or the dir being written removed under it (ENOENT)
            refused.append(_one_line(e))
        finally:
            swapper.end()
        assert _snapshot(victim) == before, f"round {i}"
    assert any("is a symbolic link: nothing is written through it" in r for r in refused), refused


def test_a_job_dir_swapped_for_a_link_under_a_held_sweep_takes_no_file_outside(cfg, tmp_path):
    """The launch holds the sweep dir (as rovermarl.train does); its job dir is swapped for a link meanwhile."""
    victim = _victim(tmp_path)
    before, refused = _snapshot(victim), []
    for i in range(ROUNDS):
        sweep = tmp_path / f"sweep{i}"
        (sweep / "job").mkdir(parents=True)
        swapper = Swapper(sweep / "job", victim, sweep / ".lock")
        with lock.hold(sweep):
            swapper.start()
            try:
                run_job(cfg, sweep / "job")
            except OSError as e:
                refused.append(_one_line(e))
            finally:
                swapper.end()
        assert _snapshot(victim) == before, f"round {i}"
    assert refused, "the swapper never caught a write"


@pytest.mark.parametrize("what", ["atomic_open", "remove", "replace"])
def test_each_write_through_a_toggled_dir_fails_or_stays_inside(tmp_path, what):
    """A dir (``figures/``) toggled between a dir and a link to a victim dir while a writer writes into it."""
    victim = _victim(tmp_path)
    before = _snapshot(victim)
    root = tmp_path / "sweep"
    (root / "figures").mkdir(parents=True)
    swapper = Swapper(root / "figures", victim, root)
    swapper.start()
    refused = 0
    try:
        with atomic.beneath(root):
            i, deadline = 0, time.monotonic() + 20
            while (swapper.swaps < 50 or i < 300) and time.monotonic() < deadline:   # writes all through 50 swaps
                i += 1
                try:
                    if what == "atomic_open":
                        with atomic.atomic_open(root / "figures" / "precious") as f:
                            f.write(b"overwritten %d" % i)
                    elif what == "remove":
                        atomic.remove(root / "figures" / "run.json")
                    else:
                        with atomic.atomic_open(root / "figures" / "curve.npz") as f:
                            f.write(b"new")
                        atomic.replace(root / "figures" / "curve.npz", root / "figures" / "summary.json")
                except Unsafe as e:
                    assert "is a symbolic link" in _one_line(e)
                    refused += 1
                except FileNotFoundError:                           # the real dir moved away for a moment
                    pass
    finally:
        swapper.end()
    assert _snapshot(victim) == before
    assert swapper.swaps >= 50 and refused > 0


def test_a_write_outside_the_dir_being_written_is_refused(tmp_path):
    with atomic.beneath(tmp_path / "sweep"), pytest.raises(Unsafe, match="lies outside"):
        with atomic.atomic_open(tmp_path / "sweep" / ".." / "elsewhere"):
            pass
    assert not (tmp_path / "elsewhere").exists()


def test_a_lock_file_hard_linked_to_a_file_elsewhere_is_refused_and_left_as_it_was(cfg, tmp_path):
    """issue 51: a relaunch truncated and rewrote in place a .lock that was a hard link to a file elsewhere."""
    victim = _victim(tmp_path)
    before = _snapshot(victim)
    job = tmp_path / "job"
    job.mkdir()
    os.link(victim / ".lock", job / ".lock")
    with pytest.raises(Unsafe) as err:
        run_job(cfg, job)
    assert _one_line(err.value) == f"{job / '.lock'} has 2 hard links (a file elsewhere shares it): refused (remove " \
                                   "it; a lock is this dir's own file)"
    assert _snapshot(victim) == before


def test_a_dead_holders_lock_file_is_taken_over_and_names_the_new_holder(tmp_path):
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / ".lock").write_text("PID 1 on elsewhere since long ago, a line longer than the new holder's\n")
    with lock.hold(tmp_path / "d"):
        line = (tmp_path / "d" / ".lock").read_text()
        assert line.startswith(f"PID {os.getpid()} on {socket.gethostname()} since ") and line.count("\n") == 1


HOLD = """
import os, sys, time
from rovermarl.record import lock
d, log = sys.argv[1], sys.argv[2]
try:
    with lock.hold(d):
        with open(log, "a") as f:
            f.write(f"in {os.getpid()}\\n"); f.flush(); time.sleep(0.02); f.write(f"out {os.getpid()}\\n")
except lock.Locked:
    pass
"""


def test_launches_racing_for_one_lock_never_hold_it_together(tmp_path):
    """The lock file is replaced by each holder's (its line in a new file): in every round of three processes that
    race for it, the holds never overlap and at least one gets it."""
    for i in range(ROUNDS // 2):
        d, log = tmp_path / f"d{i}", tmp_path / f"log{i}"
        procs = [subprocess.Popen([sys.executable, "-c", HOLD, str(d), str(log)], cwd=ROOT) for _ in range(3)]
        for p in procs:
            assert p.wait(timeout=60) == 0
        events = log.read_text().split("\n")[:-1]
        assert events and len(events) % 2 == 0
        for k in range(0, len(events), 2):                        # in, out, in, out: never two in at once
            assert events[k].startswith("in ") and events[k + 1] == "out " + events[k][3:], events


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A finished one-job sweep made by the CLI (its .hydra/, multirun.yaml, train.log): tests tamper with copies."""
    path = tmp_path_factory.mktemp("races") / "sweep"
    proc = run_cli(*SWEEP, f"hydra.sweep.dir={path}", "~hydra.callbacks.plot", timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return path


@pytest.mark.parametrize("name", [".lock", "multirun.yaml", f"{JOB}/.lock", f"{JOB}/.hydra/config.yaml",
                                  f"{JOB}/.hydra/overrides.yaml", f"{JOB}/train.log"])
def test_a_relaunch_refuses_hard_linked_hydra_and_lock_files(sweep, tmp_path, name):
    """Hydra rewrites .hydra/*.yaml and multirun.yaml in place and appends to train.log: shared with a file
    elsewhere, the relaunch refuses the dir in one line and the file elsewhere is unchanged."""
    sw = tmp_path / "sweep"
    shutil.copytree(sweep, sw)
    victim = _victim(tmp_path)
    (sw / name).unlink(missing_ok=True)
    os.link(victim / "precious", sw / name)
    before = _snapshot(victim)
    proc = run_cli(*SWEEP, f"hydra.sweep.dir={sw}", "~hydra.callbacks.plot", cwd=tmp_path, env=ENV, timeout=300)
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert proc.returncode == 2 and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert lines[0].startswith("rovermarl.train: error: ") and f"{sw / name} has 2 hard links" in lines[0], lines[0]
    assert _snapshot(victim) == before


# ---- ray.address: a port that accepts, then closes or says nothing -----------------------------------------------
SERVER = """
import socket, sys
s = socket.socket(); s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1); s.bind(("127.0.0.1", 0)); s.listen(50)
print(s.getsockname()[1], flush=True)
held = []
while True:
    c, _ = s.accept()
    c.close() if sys.argv[1] == "close" else held.append(c)
    print("accepted", flush=True)
"""


@pytest.fixture(params=["close", "silent"])
def fake_ray(request):
    server = subprocess.Popen([sys.executable, "-c", SERVER, request.param], stdout=subprocess.PIPE, text=True)
    port = int(server.stdout.readline())
    yield request.param, f"127.0.0.1:{port}"
    server.kill()
    server.wait()


def _train(address: str, run: Path) -> list[str]:
    return [sys.executable, "-m", "rovermarl.train", "generations=3", "seeds=1", f"ray.address={address}",
            f"hydra.run.dir={run}"]


def test_a_ray_address_that_accepts_and_closes_or_stays_silent_is_one_line_in_seconds(fake_ray, tmp_path):
    kind, address = fake_ray
    t0 = time.monotonic()
    proc = subprocess.run(_train(address, tmp_path / "run"), cwd=ROOT, capture_output=True, text=True, timeout=60)
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-2000:]
    assert lines[0].startswith(f"rovermarl.train: error: ray.address={address}: cannot start or join Ray: nothing "
                               f"answers as Ray at {address} ("), lines[0]
    assert time.monotonic() - t0 < 40 and not (tmp_path / "run").exists()


@pytest.mark.parametrize("sig, code, word", [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")])
def test_a_signal_during_the_wait_for_ray_ends_it(tmp_path, sig, code, word):
    server = subprocess.Popen([sys.executable, "-c", SERVER, "silent"], stdout=subprocess.PIPE, text=True)
    address = f"127.0.0.1:{int(server.stdout.readline())}"
    try:
        proc = subprocess.Popen(_train(address, tmp_path / "run"), cwd=ROOT, stderr=subprocess.PIPE, text=True)
        assert server.stdout.readline().strip() == "accepted"   # the launch is connected and waiting
        assert proc.poll() is None
        t0 = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
        assert time.monotonic() - t0 < 10
        lines = [x for x in err.splitlines() if x.strip()]
        assert proc.returncode == code and lines == [f"rovermarl.train: {word}; relaunch the same command to resume"], \
            err[-2000:]
    finally:
        server.kill()
        server.wait()


def test_run_json_written_beneath_the_job_dir_names_its_file_on_a_write_error(cfg, tmp_path, monkeypatch):
    """An OSError of a write names the file it was for, not its temp copy."""
    monkeypatch.setenv(atomic.FAULT, "summary.json:enospc")
    with pytest.raises(OSError) as err:
        run_job(cfg, tmp_path / "job")
    assert err.value.filename == str(tmp_path / "job" / "summary.json")
    assert not [p for p in (tmp_path / "job").rglob(".*.tmp")]
    assert json.loads((tmp_path / "job" / "runs" / "seed_000" / "run.json").read_text())["seed"] == 0


def test_a_job_dir_swapped_for_a_link_during_heldout_merge_takes_no_file_outside(sweep, tmp_path, capsys):
    """issue 51: swapping a job dir during ``heldout merge`` (``studies/heldout/report.py``) wrote outside 2 of 10
    times."""
    main = study_module("heldout").main

    committed = json.loads((sweep / JOB / "summary.json").read_text())
    for key in ("heldout_score", "median_heldout_score"):
        committed.pop(key)
    victim = tmp_path / "outside"
    victim.mkdir()
    (victim / "summary.json").write_text(json.dumps(committed))
    before, refused = _snapshot(victim), 0
    for i in range(ROUNDS // 2):
        results = tmp_path / f"results{i}"
        (results / JOB).mkdir(parents=True)
        (results / JOB / "summary.json").write_text(json.dumps(committed))
        swapper = Swapper(results / JOB, victim, results)
        swapper.start()
        try:
            main(["merge", str(sweep), str(results)])
        except SystemExit as e:
            assert e.code == 2
            refused += 1
        finally:
            swapper.end()
        assert _snapshot(victim) == before, f"round {i}"
    err = [x for x in capsys.readouterr().err.splitlines() if "error" in x]
    assert refused and len(err) == refused and all("symbolic link" in x or "No such file" in x for x in err), err


def test_a_run_dir_swapped_for_a_link_during_replay_resim_takes_no_file_outside(sweep, tmp_path):
    """``replay --resim`` writes its .rrd beneath the job dir: the run dir toggled for a link to a copy elsewhere."""
    from rovermarl.replay import ReplayError, resimulate

    victim = tmp_path / "outside"
    shutil.copytree(sweep / JOB / "runs" / "seed_000", victim)         # reads through the link still succeed
    before, refused = _snapshot(victim), 0
    for i in range(ROUNDS // 3):
        job = tmp_path / f"job{i}"
        shutil.copytree(sweep / JOB, job)
        swapper = Swapper(job / "runs" / "seed_000", victim, job)
        swapper.start()
        try:
            resimulate(job / "runs" / "seed_000", None, None)
        except (OSError, ReplayError) as e:               # the link refused, or the run dir gone for a moment
            assert "symbolic link" in _one_line(e) or "No such file" in str(e) or "needs genomes.npy" in str(e)
            refused += 1
        finally:
            swapper.end()
        assert _snapshot(victim) == before, f"round {i}"
    assert refused


def test_a_lock_file_replaced_while_being_locked_is_refused_and_the_other_file_left_as_it_was(tmp_path):
    """The check filelock's on_acquired runs: the descriptor it locked must be the held dir's own .lock."""
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / ".lock").write_text("")
    (tmp_path / "other").write_text("precious\n")
    with atomic.beneath(tmp_path / "d") as dfd, open(tmp_path / "other", "r+b") as other:
        with pytest.raises(Unsafe, match=r"\.lock was replaced while it was being locked: refused"):
            lock._stamp(dfd, tmp_path / "d" / ".lock", other.fileno())
    assert (tmp_path / "other").read_text() == "precious\n"
