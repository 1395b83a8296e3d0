"""Ctrl-C (SIGINT) and SIGTERM mid-sweep: one line, exit 130 / 143, no traceback, no Ray process left behind; the
relaunch resumes to the curves of an uninterrupted run."""

import json
import os
import signal
import subprocess
import sys
import time

import psutil
import pytest

from tests.conftest import ROOT, assert_same_curves, run_cli, start_until_checkpoint, sweep_curves

ARGS = ("-m", "k=1,2", "setup=duo", "generations=4000", "seeds=2", "parallel.chunk=100", "checkpoint.every=100",
        "record=off", "~hydra.callbacks.plot")


def _descendants(pid: int) -> list[psutil.Process]:
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


@pytest.mark.slow
@pytest.mark.parametrize("sig,code,what", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_signal_mid_sweep_stops_in_one_line_and_the_relaunch_resumes(tmp_path, sig, code, what):
    sweep = tmp_path / "sweep"
    argv = [sys.executable, "-m", "rovermarl.train", *ARGS, "ray.num_cpus=2", f"hydra.sweep.dir={sweep}"]
    proc = start_until_checkpoint(argv, sweep)
    started = _descendants(proc.pid)                                   # this driver's Ray processes
    assert any("raylet" in p.name() for p in started)
    if sig == signal.SIGINT:
        os.killpg(proc.pid, sig)                      # Ctrl-C reaches the whole foreground process group
    else:
        proc.send_signal(sig)                         # a scheduler's SIGTERM reaches the driver
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err[-3000:]
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err and len(lines) <= 3, err[-3000:]
    assert lines[-1] == f"rovermarl.train: {what}; relaunch the same command to resume"
    _, left = psutil.wait_procs(started, timeout=10)  # Ray's processes exit with the driver's shutdown
    assert not left, [(p.pid, p.name()) for p in left]

    again = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr[-3000:]
    ref = run_cli(*ARGS, "parallel=serial", f"hydra.sweep.dir={tmp_path / 'ref'}", timeout=600)
    assert ref.returncode == 0, ref.stderr[-3000:]
    got, want = sweep_curves(sweep), sweep_curves(tmp_path / "ref")
    assert len(want) == 4
    assert_same_curves(got, want)
    launches = {job.name: [json.loads(x) for x in (job / "invocations.jsonl").read_text().splitlines()]
                for job in sweep.iterdir() if (job / "invocations.jsonl").is_file()}
    killed = [x for lines in launches.values() for x in lines if x.get("interrupted")]
    assert len(killed) == 1 and killed[0]["team_evals"] > 0, launches      # the killed launch's compute is kept
    assert not list(sweep.glob("*/launch.json"))


def test_an_interrupt_dropped_in_a_finalizer_is_delivered_again():
    """Python drops a KeyboardInterrupt raised while a finalizer runs (Ray's object refs have them); the launch's
    handlers deliver it again to the main code instead of letting the work go on."""
    from rovermarl import train

    class Finalized:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)               # the handler runs inside this finalizer
            for _ in range(1000):
                pass

    previous = signal.signal(signal.SIGINT, train._signalled)
    hook, sys.unraisablehook = sys.unraisablehook, train._unraisable
    train._SIGNALS.clear()
    try:
        with pytest.raises(KeyboardInterrupt):
            Finalized()                                       # deleted at once: the finalizer swallows the first raise
            time.sleep(5)                                     # the main code is interrupted here
        assert train._SIGNALS == [signal.SIGINT, signal.SIGINT]   # the signal, then its re-delivery
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook
        train._SIGNALS.clear()


def _marked(tag: str) -> list[int]:
    """Live processes that inherited the environment marker ``SIGNAL_TEST=tag`` (the launch's and Ray's)."""
    out = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            env = open(f"/proc/{pid}/environ", "rb").read().split(b"\0")
            state = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if f"SIGNAL_TEST={tag}".encode() in env and state != "Z":
            out.append(int(pid))
    return out


def _launch(tmp_path, tag: str) -> subprocess.Popen:
    code = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "   # as a terminal's job has it
            "os.execvp(sys.executable, [sys.executable, '-m', 'rovermarl.train', *sys.argv[1:]])")
    return subprocess.Popen([sys.executable, "-c", code, "generations=2000", "seeds=2", "ray.num_cpus=2",
                             f"hydra.run.dir={tmp_path / 'run'}"], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "SIGNAL_TEST": tag})


@pytest.mark.parametrize("moment", ["imports", "raylet up"])
@pytest.mark.parametrize("sig,code,what", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_signal_during_imports_or_ray_start_ends_in_one_line_and_leaves_no_process(tmp_path, sig, code, what,
                                                                                      moment):
    tag = f"{os.getpid()}-{time.monotonic_ns()}"
    proc = _launch(tmp_path, tag)
    if moment == "imports":
        time.sleep(0.3)
    else:                                                               # the raylet has just appeared
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline and not any(
                "raylet" in p.name() for p in _descendants(proc.pid)):
            time.sleep(0.02)
    assert proc.poll() is None
    proc.send_signal(sig)
    t0 = time.monotonic()
    _, err = proc.communicate(timeout=60)
    answered = time.monotonic() - t0
    lines = [line for line in err.splitlines() if line.strip()]
    assert proc.returncode == code, err[-3000:]
    assert "Traceback" not in err and 1 <= len(lines) <= 3 and lines[-1].startswith(f"rovermarl.train: {what}"), err
    assert answered < 5
    time.sleep(5)
    assert not _marked(tag)                                             # no process of the launch, Ray's included


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_while_the_figures_are_drawn_ends_in_one_line_and_the_relaunch_draws_them(tmp_path, sig, code):
    sweep = tmp_path / "sweep"
    args = ("-m", "k=1,2", "setup=duo", "generations=200", "seeds=2", "parallel=serial", f"hydra.sweep.dir={sweep}")
    proc = subprocess.Popen([sys.executable, "-m", "rovermarl.train", *args], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    while proc.poll() is None and not (sweep / "figures").is_dir():    # the end-of-sweep callback has begun
        time.sleep(0.002)
    assert proc.poll() is None
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    lines = [line for line in err.splitlines() if line.strip()]
    assert proc.returncode == code and "Traceback" not in err and len(lines) <= 3, err[-2000:]
    again = run_cli(*args, timeout=300)
    assert again.returncode == 0, again.stderr[-2000:]
    assert (sweep / "figures" / "curves_duo.png").is_file()


def test_an_error_raised_over_an_interrupt_is_the_interrupt(monkeypatch, tmp_path):
    """numpy's savez, cut by SIGTERM mid-write, raises ValueError from its own cleanup ("Can't close the ZIP file")
    over our Terminated: the job still ends as terminated (exit 143, one line), with no traceback."""
    from types import SimpleNamespace

    from rovermarl import train

    def savez_cut(*args, **kwargs):
        raise ValueError("Can't close the ZIP file while there is an open writing handle on it.")

    hc = SimpleNamespace(runtime=SimpleNamespace(choices={}, output_dir=str(tmp_path)),
                         overrides=SimpleNamespace(task=[]))
    monkeypatch.setattr(train.HydraConfig, "get", staticmethod(lambda: hc))
    monkeypatch.setattr(train, "run_job", savez_cut)
    monkeypatch.setattr(train, "_SIGNALS", [signal.SIGTERM])
    with pytest.raises(train.Terminated):
        train.task(None)
    monkeypatch.setattr(train, "_SIGNALS", [])
    with pytest.raises(ValueError):                                   # no signal: the error is the user's to see
        train.task(None)


@pytest.mark.parametrize("sig,raised", [(None, None), (signal.SIGTERM, SystemExit), (signal.SIGINT, KeyboardInterrupt)])
def test_a_signal_whose_exception_rays_start_swallows_is_raised_again(monkeypatch, sig, raised):
    """Ray's start can swallow what a signal's handler raised (a SIGTERM during ray.init once ended a launch with
    exit 0, the signal lost): ensure_ray sees the signal at the C level and raises it again once ray.init returns."""
    import ray

    from rovermarl.parallel import ray_backend

    def init(**kwargs):                         # the handler raises where Ray's code catches everything
        if sig is not None:
            with pytest.raises((SystemExit, KeyboardInterrupt)):
                os.kill(os.getpid(), sig)
                time.sleep(5)

    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGTERM, lambda signum, frame: sys.exit(signum))          # Ray's own SIGTERM handler
    signal.signal(signal.SIGINT, signal.default_int_handler)   # a shell's background job starts with SIGINT ignored
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", init)
    cfg = type("RayCfg", (), {"address": None, "num_cpus": 1})()
    try:
        if raised is None:
            ray_backend.ensure_ray(cfg)
        else:
            with pytest.raises(raised) as e:
                ray_backend.ensure_ray(cfg)
            assert raised is KeyboardInterrupt or e.value.code == signal.SIGTERM
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
