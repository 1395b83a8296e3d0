"""Configs this machine cannot do are refused in one line before any work and before Ray starts; a feasible but
long job states its estimated time."""

import re
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np
import psutil
import pytest

from rovermarl.runner import budget
from tests.conftest import ROOT, make_cfg, run_cli


@pytest.fixture
def ray_tmpdir():
    """A fresh, short RAY_TMPDIR (Ray's unix sockets need a short path): a Ray the CLI starts makes ``ray/`` there
    (its session dirs; the dir stays after the CLI stops that Ray), and its processes' command lines name it."""
    with tempfile.TemporaryDirectory(prefix="rmray") as d:
        yield Path(d)


@pytest.mark.parametrize("override,message", [
    ("generations=1000000000", "one run needs about"),
    ("policy.hidden=100000000", "the job needs about"),
    ("env.steps=1000000000", "one team evaluation would take about"),
    ("env.n_rovers=100000", "one team evaluation would take about"),
    ("env.episodes=1000000000", "one team evaluation would take about"),
    ("mutation.sigma=1e308", "must be at most 1e+100"),
])
def test_infeasible_configs_are_refused_in_one_line_before_ray(override, message, ray_tmpdir):
    # the default parallel=ray with an embedded Ray (1 CPU): had the refusal come after Ray, Ray would have started
    proc = run_cli(override, "ray.num_cpus=1", env={"RAY_TMPDIR": str(ray_tmpdir)}, timeout=300)  # a hang guard
    assert proc.returncode == 2, proc.stderr[-2000:]
    key, _, value = override.partition("=")
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"rovermarl.train: error: {key}=") and message in lines[0], lines
    assert not re.search(r"\bray\b", proc.stderr, re.IGNORECASE) and proc.stdout == ""   # nothing from or about Ray
    assert list(ray_tmpdir.iterdir()) == []                    # no Ray session: Ray was neither started nor joined
    left = [p.info["name"] for p in psutil.process_iter(["name", "cmdline"])
            if str(ray_tmpdir) in " ".join(p.info["cmdline"] or [])]
    assert left == []                                          # no raylet, gcs_server, ... of this launch


def test_a_feasible_slow_job_states_its_estimate_and_starts(tmp_path):
    argv = [sys.executable, "-m", "rovermarl.train", "policy.hidden=100000", "parallel=serial", "record=off",
            f"hydra.run.dir={tmp_path}"]
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline, seen = time.monotonic() + 120, ""
        while time.monotonic() < deadline and "estimated about" not in seen:
            seen = proc.stdout.readline()
        assert "policy.hidden=100000: estimated about 32 h on 1 CPUs" in seen, seen
    finally:
        proc.kill()
        proc.wait()


def test_the_estimate_scales_with_the_work():
    from rovermarl.runner.chunk import to_plain
    small, big = (budget.estimate(to_plain(make_cfg(*o, "parallel=serial"))) for o in
                  ((), ("generations=40000", "policy.hidden=32")))
    assert big.job_s > 3 * small.job_s and big.memory["records"] == pytest.approx(2 * small.memory["records"], 1e-3)
    assert budget.duration(90) == "1.5 min" and budget.duration(7200) == "2 h" and budget.size(3e9) == "3 GB"


def test_the_estimate_counts_each_algorithms_evaluations_per_generation():
    from rovermarl.runner.chunk import parts, to_plain

    def job_s(*overrides):
        plain = to_plain(make_cfg(*overrides, "generations=1000", "parallel=serial"))
        built = parts(plain)
        per = built.algorithm.evaluations_per_generation(built.evaluation["fresh_ic"])
        return budget.estimate(plain, 32, per).job_s, per

    base, one = job_s()
    ccea, eleven = job_s("algorithm=ccea")
    fresh, two = job_s("evaluation.fresh_ic=true")
    assert (one, eleven, two) == (1, 11, 2)
    assert ccea / base == pytest.approx((1000 * 11 + 1) / 1001) and fresh / base == pytest.approx(2001 / 1001)


def test_runs_that_do_not_fit_in_memory_at_once_stream_in_batches(tmp_path, monkeypatch, caplog):
    from rovermarl.runner.chunk import parts, to_plain
    from rovermarl.runner.job import run_job
    from rovermarl.runner.validate import series_bytes
    from tests.conftest import sweep_curves

    cfg = make_cfg("generations=300", "seeds=5", "parallel=serial", "record=off")
    whole = run_job(cfg, tmp_path / "all" / "job")
    per_series = series_bytes(parts(to_plain(cfg)).algorithm.series)
    per_run = budget.run_bytes(to_plain(cfg), per_series)
    fits_two = partial(budget.batch_size, memory=4 * 2.5 * per_run)              # two runs fit at once
    assert fits_two(to_plain(cfg), per_series) == 2
    monkeypatch.setattr(budget, "batch_size", fits_two)
    with caplog.at_level("INFO", logger="rovermarl"):
        streamed = run_job(cfg, tmp_path / "streamed" / "job")
    assert "5 runs stream in batches of 2" in caplog.text
    assert streamed["final_score"] == whole["final_score"] and streamed["team_evals"] == whole["team_evals"]
    assert streamed["first_generation_reaching"] == whole["first_generation_reaching"]
    got, want = sweep_curves(tmp_path / "streamed"), sweep_curves(tmp_path / "all")
    assert len(want) == 5 and all(np.array_equal(got[k]["score"], want[k]["score"]) for k in want)
    huge = to_plain(make_cfg("seeds=100000", "parallel=serial"))                 # 100,000 runs: refused before
    assert budget.check(huge).memory["records"] <= 0.25 * budget.available_memory() + per_run
