"""analysis verify: every committed final team re-scores to its run's recorded final and held-out scores, and a
changed team, a changed score or a doctored genomes.npz is caught (exit 1 or one line, exit 2)."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from rovermarl.analysis.verify import verify
from tests.conftest import ROOT

JOB = "env.obs_radius=2.5,env.poi_distance=13,generations=200000,k=1,seed=16,setup=duo"   # a committed job


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "rovermarl.analysis", "verify", *map(str, args)],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)


@pytest.fixture
def job(tmp_path):
    shutil.copytree(ROOT / "results" / "radius" / JOB, tmp_path / JOB)
    return tmp_path / JOB


def test_a_committed_job_re_scores(job):
    proc = _cli(job.parent)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [f"ok  {JOB}: 16 teams re-score: final scores 16/16, held-out 16/16 equal"]


def test_a_changed_team_or_score_is_caught(job):
    with np.load(job / "genomes.npz") as z:
        seed, genomes = z["seed"], z["genomes"].copy()
    genomes[3] = 0.0                     # an all-zero team stands still near the centre: score 0, not the recorded
    np.savez_compressed(job / "genomes.npz", seed=seed, genomes=genomes)
    (checked,) = verify(job.parent)
    recorded = json.loads((job / "summary.json").read_text())["final_score"][str(seed[3])]
    assert not checked.ok and checked.line == f"seed {seed[3]}: final score 0.0 re-scored, {recorded!r} recorded"
    shutil.copy(ROOT / "results" / "radius" / JOB / "genomes.npz", job / "genomes.npz")
    summary = json.loads((job / "summary.json").read_text())
    summary["final_score"][str(seed[0])] += 0.0625
    (job / "summary.json").write_text(json.dumps(summary))
    proc = _cli(job.parent)
    assert proc.returncode == 1 and proc.stdout.startswith(f"DIFFERS  {JOB}: seed {seed[0]}: final score")
    assert proc.stderr.strip().splitlines()[-1] == "rovermarl.analysis: error: 1 of 1 jobs do not re-score"


def test_a_doctored_genomes_file_is_one_line(job):
    with np.load(job / "genomes.npz") as z:
        seed, genomes = z["seed"], z["genomes"]
    np.savez_compressed(job / "genomes.npz", seed=seed, genomes=genomes, extra=np.zeros(3))
    proc = _cli(job.parent)
    assert proc.returncode == 2 and "holds 3 members, more than the 2 it may have" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    np.savez_compressed(job / "genomes.npz", seed=seed, genomes=genomes[:, :, :5])
    proc = _cli(job.parent)
    assert proc.returncode == 2 and "has shape" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_a_plugin_worlds_job_re_scores_only_when_trusted(tmp_path):
    """A world plug-in's job (D++ on random_pois, made here): refused in one line that names the flag to pass, which
    verify takes; with it every team re-scores on its episodes' own POIs."""
    from tests.conftest import run_cli
    job = tmp_path / "job"
    made = run_cli("env=random_pois", f"hydra.searchpath=[file://{ROOT}/examples/random_pois]", "algorithm=ccea",
                   "algorithm.reward=dpp", "generations=3", "seeds=2", "parallel=serial", "record=off",
                   f"hydra.run.dir={job}", timeout=600)
    assert made.returncode == 0, made.stderr[-2000:]
    refused = _cli(job)
    assert refused.returncode == 2 and "pass --trust-config" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    proc = _cli("--trust-config", job)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [f"ok  {job.name}: 2 teams re-score: final scores 2/2, held-out 2/2 equal"]
