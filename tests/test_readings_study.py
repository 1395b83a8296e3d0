"""The readings study: launchers/readings.sh (tiny budget, interrupted and resumed), the lifting rule, and the
committed report (results/readings -> docs/REPRODUCTION.md)."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from tests.conftest import ROOT, study_module

readings = study_module("readings")

COMMITTED = ROOT / "results" / "readings"


def _job(reading, method, final_step, setup="duo"):
    runs = {str(i): {"final": v, "final_step": v, "heldout": v - 0.1, "first": {"4": 10 if v >= 4 else None,
                                                                               "5": 20 if v >= 5 else None}}
            for i, v in enumerate(final_step)}
    return {"job": f"{reading},{method},{setup}", "reading": reading, "setup": setup, "method": method,
            "generations": 100, "runs": runs, "compute": {"launches": 1, "wall_time_s": 1.0, "team_evals": 101},
            "median_heldout_score": float(np.median(final_step)) - 0.1}


def test_lifting_needs_a_higher_median_or_more_runs_at_5():
    spec = [4, 4, 4, 5]
    jobs = [_job("spec", "k=1", spec), _job("spec", "k=2", [4, 4, 4, 4]),
            _job("env.speed=clip", "k=1", [4, 4, 4, 5]),              # as SPEC: no lift
            _job("env.reward=any_step", "k=1", [4, 4, 5, 5]),         # more runs at 5
            _job("env.poi_type=sign", "k=2", [4, 4.5, 4.5, 4]),       # higher median, same runs at 5
            _job("env.poi_type=value", "k=1", [3, 3, 3, 6]),          # lower median, same runs at 5
            _job("env.reward=any_step+env.poi_type=sign", "k=1", [6, 6, 6, 6])]   # combinations never count
    assert readings.lifting(jobs) == ["env.reward=any_step", "env.poi_type=sign"]


def test_report_names_budget_seeds_compute_and_the_tests(tmp_path):
    jobs = [_job("spec", "k=1", [4, 4, 4, 5]), _job("env.reward=any_step", "k=1", [5, 5, 6, 6]),
            _job("env.reward=any_step", "k=1", [4, 5, 5, 5], setup="solo")]
    (tmp_path / "readings.json").write_text(json.dumps({"jobs": jobs}))
    text, numbers = readings.report(tmp_path)
    assert "Budget: 100 generations per run; 4 seeds per job" in text
    assert "Compute: 303 team evaluations" in text
    assert "### duo" in text and "### solo" in text
    row = next(line for line in text.splitlines() if line.startswith("| `env.reward=any_step` | k=1 | 5.5"))
    assert "| 4/4 [" in row and "| 2/4 [" in row                        # runs at 5, runs at 6
    assert numbers["env.reward=any_step,k=1,duo"]["vs_spec"]["p"] < 0.1
    assert numbers["lifting"] == ["env.reward=any_step"]
    assert (tmp_path / "readings.md").read_text() == text


def test_reading_of_a_job_ignores_method_and_runtime_overrides():
    assert readings.reading_of(["k=1", "setup=duo", "generations=50", "record=off"]) == "spec"
    assert readings.reading_of(["env.speed=clip", "team=homogeneous", "setup=duo"]) == "env.speed=clip"
    assert readings.reading_of(["evaluation.fresh_ic=True", "k=1"]) == "evaluation.fresh_ic=true"
    assert readings.reading_of(["mutation.sigma=0.316", "env.reward=any_step", "k=2"]) == \
        "env.reward=any_step+mutation.sigma=0.316"


@pytest.mark.skipif(not (COMMITTED / "readings.json").is_file(), reason="the study's results are not committed yet")
def test_committed_report_is_recomputed_from_the_committed_numbers(tmp_path):
    shutil.copy(COMMITTED / "readings.json", tmp_path / "readings.json")
    text, _ = readings.report(tmp_path)
    assert text == (COMMITTED / "readings.md").read_text()
    assert text in (ROOT / "docs" / "REPRODUCTION.md").read_text()


def _launch(env, cwd):
    return subprocess.Popen(["bash", str(ROOT / "launchers" / "readings.sh"), "parallel=serial", "record=off",
                             "~hydra.callbacks.plot"], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


@pytest.mark.slow
def test_launcher_runs_as_documented_and_resumes_after_an_interruption(tmp_path):
    out, results = tmp_path / "sweep", tmp_path / "results"
    env = {**os.environ, "GENERATIONS": "30", "SEEDS": "2", "OUT": str(out), "RESULTS": str(results),
           "READINGS": "env.reward=any_step", "PYTHON": sys.executable}
    first = _launch(env, tmp_path)
    deadline = time.monotonic() + 300
    while not list(out.glob("*/summary.json")) and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    os.killpg(first.pid, signal.SIGKILL)                               # the launcher and its train process
    first.wait()
    done = sorted(p.parent for p in out.glob("*/summary.json"))
    assert done, "no job finished before the interruption"
    second = _launch(env, tmp_path)
    _, err = second.communicate(timeout=600)
    assert second.returncode == 0, err[-3000:]
    for job in done:                                                   # not recomputed: one launch each
        assert len((job / "invocations.jsonl").read_text().splitlines()) == 1, job.name
    data = json.loads((results / "readings.json").read_text())
    got = {(j["reading"], j["method"]) for j in data["jobs"] if j["setup"] == "duo"}
    assert got == {(r, m) for r in ("spec", "env.reward=any_step") for m in ("k=1", "k=2", "homogeneous")}
    assert all(len(j["runs"]) == 2 and j["generations"] == 30 for j in data["jobs"])
    assert "readings that lift duo:" in err
    assert (results / "readings.md").read_text().startswith("<!-- generated by")
