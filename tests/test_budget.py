"""Configs this machine cannot do are refused in one line before any work and before Ray starts; a feasible but
long job states its estimated time."""

import subprocess
import sys
import time

import pytest

from rovermarl.runner import budget
from tests.conftest import ROOT, make_cfg, run_cli

NOWHERE = "ray.address=10.255.255.1:6379"            # never probed: the refusals come first


@pytest.mark.parametrize("override,message", [
    ("generations=1000000000", "the job needs about"),
    ("policy.hidden=100000000", "the job needs about"),
    ("env.steps=1000000000", "one team evaluation would take about"),
    ("env.n_rovers=100000", "one team evaluation would take about"),
    ("env.episodes=1000000000", "one team evaluation would take about"),
    ("mutation.sigma=1e308", "must be at most 1e+100"),
])
def test_infeasible_configs_are_refused_in_one_line_before_ray(override, message):
    t0 = time.monotonic()
    proc = run_cli(override, NOWHERE, timeout=60)
    assert time.monotonic() - t0 < 10
    assert proc.returncode == 2
    key, _, value = override.partition("=")
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"rovermarl.train: error: {key}=") and message in lines[0]


def test_a_feasible_slow_job_states_its_estimate_and_starts(tmp_path):
    argv = [sys.executable, "-m", "rovermarl.train", "policy.hidden=100000", "parallel=serial", "record=off",
            f"hydra.run.dir={tmp_path}"]
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline, seen = time.monotonic() + 120, ""
        while time.monotonic() < deadline and "estimated about" not in seen:
            seen = proc.stdout.readline()
        assert "policy.hidden=100000: estimated about 4.7 days on 1 CPUs" in seen, seen
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
