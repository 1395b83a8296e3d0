"""The fault-injection suite, in the spirit of SQLite's crash and I/O-error tests: at every write point of a run,
the process is killed there (SIGKILL, its temp copy complete but not renamed) or the write fails as a full or
broken disk does (ENOSPC, EIO, through the ``ROVERMARL_FAULT`` hook of :func:`rovermarl.record.atomic.fault`);
then the job is relaunched, and nothing may be lost: the results equal an undisturbed job's, bit for bit, every
run verifies, no temp file is left, and a failed write ends in one line with exit 1."""

import json
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from rovermarl.record.atomic import FAULT
from rovermarl.record.outputs import verify
from rovermarl.runner.job import run_job
from tests.conftest import ROOT, make_cfg, run_cli

ARGS = ("setup=duo", "k=adaptive", "generations=300", "seeds=2", "parallel=serial", "parallel.chunk=100",
        "checkpoint.every=100", "record.every=1")
# Every file a job writes, in the order it writes them (rovermarl.record.outputs, rovermarl.runner.job).
WRITE_POINTS = ("config.yaml", "launch.json", "checkpoint.bin", "curve.npz", "genomes.npy", "initial_conditions.npz",
                "behaviour.npz", "occupancy.npz", "run.rrd", "run.json", "summary.json", "invocations.jsonl")


def _job_files(job) -> dict:
    """Every result file of a job dir that must not depend on how the job got there: the runs' arrays and scores."""
    out = {}
    for run in sorted(job.glob("runs/seed_*")):
        for name in ("curve.npz", "initial_conditions.npz", "behaviour.npz", "occupancy.npz"):
            with np.load(run / name) as z:
                out[f"{run.name}/{name}"] = {k: z[k] for k in z.files}
        out[f"{run.name}/genomes.npy"] = {"": np.load(run / "genomes.npy")}
        meta = json.loads((run / "run.json").read_text())
        assert verify(run, meta) is None
        out[f"{run.name}/run.json"] = {"": np.array([meta["final_score"], meta["heldout_score"]])}
    summary = json.loads((job / "summary.json").read_text())
    out["summary"] = {"": np.array([summary["final_score"][s] for s in sorted(summary["final_score"])])}
    return out


def _assert_same(got: dict, want: dict) -> None:
    assert got.keys() == want.keys()
    for key in want:
        for name in want[key]:
            np.testing.assert_array_equal(got[key][name], want[key][name], err_msg=f"{key}:{name}")


def _leftovers(job) -> list:
    return [p for p in job.rglob("*") if p.name.endswith(".tmp") or p.name.startswith(".checkpoint")]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    job = tmp_path_factory.mktemp("ref") / "job"
    run_job(make_cfg(*ARGS), job)
    return _job_files(job)


@pytest.mark.parametrize("point", WRITE_POINTS)
def test_killed_at_each_write_point_then_relaunched_loses_nothing(tmp_path, reference, point):
    job = tmp_path / "job"
    code = ("import sys; from rovermarl.config import compose_config; from rovermarl.runner.job import run_job; "
            "run_job(compose_config(*sys.argv[2:]), sys.argv[1])")
    proc = subprocess.run([sys.executable, "-c", code, str(job), *ARGS], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, FAULT: f"{point}:kill"}, timeout=300)
    assert proc.returncode == -signal.SIGKILL, (point, proc.returncode, proc.stderr[-2000:])
    run_job(make_cfg(*ARGS), job)                                               # the relaunch
    _assert_same(_job_files(job), reference)
    assert not _leftovers(job)


@pytest.mark.parametrize("action", ["enospc", "eio"])
@pytest.mark.parametrize("point", WRITE_POINTS)
def test_a_failed_write_at_each_point_raises_leaves_no_temp_file_and_the_relaunch_completes(
        tmp_path, reference, monkeypatch, point, action):
    job = tmp_path / "job"
    monkeypatch.setenv(FAULT, f"{point}:{action}")
    with pytest.raises(OSError) as failed:
        run_job(make_cfg(*ARGS), job)
    assert failed.value.filename and os.path.basename(failed.value.filename) == point
    assert not _leftovers(job)
    monkeypatch.delenv(FAULT)
    run_job(make_cfg(*ARGS), job)
    _assert_same(_job_files(job), reference)


@pytest.mark.parametrize("point,backend", [("run.rrd", "serial"), ("run.rrd", "ray"), ("checkpoint.bin", "ray"),
                                           ("summary.json", "serial")])
def test_a_failed_write_ends_the_launch_in_one_line_with_exit_1(tmp_path, point, backend):
    sweep = tmp_path / "sweep"
    args = [a for a in ARGS if not a.startswith("parallel=")]
    proc = run_cli(*args, f"parallel={backend}", "ray.num_cpus=1", f"hydra.run.dir={sweep}",
                   env={FAULT: f"{point}:enospc"}, timeout=300)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr[-3000:]
    assert lines[0].startswith("rovermarl.train: error: ") and f"cannot write {sweep}" in lines[0]
    assert f"/{point}: No space left on device; fix it and relaunch the same command to resume" in lines[0]
    assert not _leftovers(sweep)


def test_the_warm_ups_faults_off_leaves_other_threads_and_the_environment_alone(tmp_path, monkeypatch):
    """The compile warm-up runs in a thread while Ray starts: Ray's processes must still get ROVERMARL_FAULT."""
    import threading

    from rovermarl.record.atomic import fault, faults_off
    monkeypatch.setenv(FAULT, "run.json:eio")
    seen = []
    with faults_off():
        fault(tmp_path / "run.json")                               # off in this thread
        assert os.environ[FAULT] == "run.json:eio"
        other = threading.Thread(target=lambda: seen.append(_raises(lambda: fault(tmp_path / "run.json"))))
        other.start()
        other.join()
    assert seen == [True]
    assert _raises(lambda: fault(tmp_path / "run.json"))           # on again after it


def _raises(f) -> bool:
    try:
        f()
    except OSError:
        return True
    return False


def test_a_launch_killed_writing_its_figures_leaves_no_temp_file_after_the_relaunch(tmp_path):
    """Found from outside: a sweep killed (SIGKILL) while writing figures/index.json kept its temp file after a
    relaunch, which cleaned only job dirs."""
    sweep = tmp_path / "sweep"
    args = ("-m", "k=1", "setup=duo", "generations=50", "seeds=1", "parallel=serial", "record=off",
            f"hydra.sweep.dir={sweep}")
    killed = run_cli(*args, env={FAULT: "index.json:kill"}, timeout=300)
    assert killed.returncode == -signal.SIGKILL, killed.stderr[-2000:]
    assert [p.name for p in (sweep / "figures").glob(".index.json.*.tmp")]        # the fault left it
    relaunch = run_cli(*args, timeout=300)
    assert relaunch.returncode == 0, relaunch.stderr[-2000:]
    assert not [p for p in sweep.rglob("*.tmp")] and (sweep / "figures" / "index.json").is_file()
