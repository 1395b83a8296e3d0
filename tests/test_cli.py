"""End to end: the CLI sweep, serial == Ray, and a user selector from outside the package."""

import json

import numpy as np
import pytest

from rovermarl.runner.job import run_job
from tests.conftest import ROOT, make_cfg, run_cli


@pytest.mark.slow
def test_paper_sweep_cli_tiny_budget(tmp_path):
    sweep = tmp_path / "sweep"
    proc = run_cli("-m", "k=1,2,4,adaptive", "setup=solo,duo", "generations=20", "seeds=2",
                   f"hydra.sweep.dir={sweep}", "ray.num_cpus=2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    jobs = sorted(p.name for p in sweep.iterdir() if p.is_dir() and p.name != "figures")
    assert jobs == sorted(f"generations=20,k={k},setup={s}"  # seeds: not in names, a larger count reuses runs
                          for k in (1, 2, 4, "adaptive") for s in ("solo", "duo"))
    for job in jobs:
        summary = json.loads((sweep / job / "summary.json").read_text())
        assert summary["choices"]["k"] == job.split("k=")[1].split(",")[0]
        assert len(summary["final_score"]) == 2 and summary["team_evals"] == 2 * 21
        assert set(summary["first_generation_reaching"]) == {"3", "4", "5", "6"}
        for seed in (0, 1):
            run = sweep / job / "runs" / f"seed_{seed:03d}"
            with np.load(run / "curve.npz") as c:
                assert c["score"].shape == (21,) and c["k"].shape == (20,) and c["accepted"].shape == (20,)
                assert ("probs" in c.files) == ("adaptive" in job)
                if "adaptive" in job:
                    assert c["probs"].shape == (20, 4)
                assert summary["final_score"][str(seed)] == c["score"][-1]
            assert np.load(run / "genomes.npy").shape == (4, 658)
            with np.load(run / "initial_conditions.npz") as ic:
                assert ic["xy"].shape == (16, 4, 2) and ic["heading"].shape == (16, 4)
        assert (sweep / job / ".hydra" / "config.yaml").exists()
    assert "median final score" in proc.stderr + proc.stdout


def _curves(job_dir, seeds):
    out = {}
    for s in seeds:
        with np.load(job_dir / "runs" / f"seed_{s:03d}" / "curve.npz") as c:
            out[s] = {k: c[k] for k in c.files}
        out[s]["genomes"] = np.load(job_dir / "runs" / f"seed_{s:03d}" / "genomes.npy")
    return out


def test_serial_equals_ray(ray_session, tmp_path):
    overrides = ["k=adaptive", "setup=duo", "generations=150", "seeds=3", "seed=11", "parallel.chunk=40"]
    serial = run_job(make_cfg(*overrides, "parallel=serial"), tmp_path / "serial")
    on_ray = run_job(make_cfg(*overrides, "parallel=ray", "parallel.workers=2"), tmp_path / "ray")
    assert serial["final_score"] == on_ray["final_score"]
    a, b = _curves(tmp_path / "serial", [11, 12, 13]), _curves(tmp_path / "ray", [11, 12, 13])
    for s in a:
        assert set(a[s]) == {"score", "k", "accepted", "switched", "child_score", "probs", "genomes"}
        for key in a[s]:
            np.testing.assert_array_equal(a[s][key], b[s][key])


def readme_block(first_line: str) -> str:
    """The README code block that starts with ``first_line``."""
    text = (ROOT / "README.md").read_text()
    start = text.index(first_line)
    return text[start:text.index("```", start)]


def test_user_selector_on_searchpath_without_editing_the_package(tmp_path):
    """The README's selector example, outside the package, on Hydra's search path, on Ray."""
    (tmp_path / "my_selectors.py").write_text(readme_block("# my_selectors.py"))
    (tmp_path / "my_conf" / "k").mkdir(parents=True)
    (tmp_path / "my_conf" / "k" / "myschedule.yaml").write_text(readme_block("# my_conf/k/myschedule.yaml"))
    proc = run_cli("k=myschedule", f"hydra.searchpath=[file://{tmp_path / 'my_conf'}]", "generations=12",
                   "seeds=2", f"hydra.run.dir={tmp_path / 'run'}", "ray.num_cpus=2", cwd=tmp_path,
                   env={"PYTHONPATH": str(tmp_path)})
    assert proc.returncode == 0, proc.stderr[-3000:]
    with np.load(tmp_path / "run" / "runs" / "seed_001" / "curve.npz") as c:
        np.testing.assert_array_equal(c["k"], [4, 4, 4, 3, 3, 3, 2, 2, 2, 1, 1, 1])
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["choices"]["k"] == "myschedule"


def test_a_selector_choosing_outside_its_arms_stops_the_cli_in_one_line(tmp_path):
    """On Ray as in this process: one line naming the selector and its file, exit 1."""
    (tmp_path / "sev.py").write_text("from rovermarl.algorithms.operators.selectors import FixedK\n\n\n"
                                     "class SevenK(FixedK):\n    def choose(self, rng):\n        return 7\n")
    (tmp_path / "conf" / "k").mkdir(parents=True)
    (tmp_path / "conf" / "k" / "seven.yaml").write_text("_target_: sev.SevenK\nvalue: 1\n")
    proc = run_cli("k=seven", f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "generations=10", "seeds=1",
                   "ray.num_cpus=2", f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path,
                   env={"PYTHONPATH": str(tmp_path)})
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr[-3000:]
    assert lines[0] == ("rovermarl.train: error: generations=10,k=seven: k-selector sev.SevenK "
                        f"({tmp_path / 'sev.py'}) chose k=7; allowed: 1 (its arms within 1..N=4)")


def test_more_workers_than_ray_cpus_completes_capped(tmp_path):
    proc = run_cli("generations=20", "seeds=4", "parallel.workers=4", "ray.num_cpus=2", "record=off",
                   f"hydra.run.dir={tmp_path}", timeout=180)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "parallel.workers=4 is more than the 2 CPUs of Ray: using 2 workers" in proc.stdout + proc.stderr
    assert sorted(json.loads((tmp_path / "summary.json").read_text())["final_score"]) == ["0", "1", "2", "3"]


def test_too_many_ic_shards_are_refused_before_ray_starts():
    import psutil
    before = {p.pid for p in psutil.process_iter() if p.name() in ("raylet", "gcs_server")}
    proc = run_cli("parallel.ic_shards=10", "ray.num_cpus=2", "generations=10")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "rovermarl.train: error: parallel.ic_shards=10: must be at most the 2 CPUs of Ray"]
    proc = run_cli("parallel.ic_shards=1000", "ray.num_cpus=2", "generations=10")      # a shard of no episode
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        "rovermarl.train: error: parallel.ic_shards=1000: must be an integer in 1..16"]
    assert {p.pid for p in psutil.process_iter() if p.name() in ("raylet", "gcs_server")} <= before
