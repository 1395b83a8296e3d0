"""Reproduction study: statistics, compact results, the C8 coupling measure, the launchers, the claims report."""

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from rovermarl.algorithms import Evaluator
from rovermarl.analysis import stats
from rovermarl.analysis.curves import Curves, log_grid
from rovermarl.analysis.export import export_fig6
from rovermarl.analysis.sweep import find_jobs
from rovermarl.runner import Run
from rovermarl.runner.job import run_job
from tests.conftest import ROOT, make_cfg, run_cli, run_study, study_module

NO_SWEEP_FIGURES = "~hydra.callbacks.plot"   # a launcher draws its study's figures itself; test_plot tests the callback


# ---- statistics ----------------------------------------------------------------------------------------------------
def test_wilson_interval_known_values():
    none, all_, half = stats.wilson(0, 16), stats.wilson(16, 16), stats.wilson(8, 16)
    assert none.value == 0 and none.low == 0 and none.high == pytest.approx(0.1936, abs=1e-4)
    assert all_.high == pytest.approx(1) and all_.low == pytest.approx(0.8064, abs=1e-4)
    assert half.low == pytest.approx(0.2800, abs=1e-4) and half.high == pytest.approx(0.7200, abs=1e-4)


def test_median_ci_handles_censored_times():
    assert stats.median_ci([3.0] * 16).fmt() == "3 [3, 3]"
    times = np.array([10.0] * 6 + [np.inf] * 10)                          # most runs never reach the level
    est = stats.median_ci(times)
    assert np.isinf(est.value) and est.fmt().startswith("never")
    est = stats.median_ci(np.arange(1.0, 17.0))
    assert est.low < est.value == 8.5 < est.high


def test_mann_whitney_orders_never_last():
    fast, slow = np.arange(16.0), np.full(16, np.inf)
    test = stats.mann_whitney(fast, slow)
    assert test.p < 1e-4 and test.effect == 0.0                          # every finite time beats "never"
    assert stats.mann_whitney(slow, slow).p == 1.0
    same = stats.mann_whitney(np.arange(16.0), np.arange(16.0))
    assert same.p > 0.9 and same.effect == pytest.approx(0.5)


# ---- exact curves from change points ---------------------------------------------------------------------------
def test_curves_from_change_points_are_exact():
    rng = np.random.default_rng(1)
    scores = [np.maximum.accumulate(np.round(rng.uniform(0, 4, 5001) * rng.uniform(0, 1, 5001) ** 8 * 16) / 16)
              for _ in range(5)]
    curves = Curves.from_scores(list(range(5)), scores)
    grid = log_grid(5000)
    assert grid[0] == 0 and grid[-1] == 5000 and np.all(np.diff(grid) > 0)
    np.testing.assert_array_equal(curves.at(grid), np.array([s[grid] for s in scores]))
    for i, s in enumerate(scores):
        np.testing.assert_array_equal(curves.full(i), s)
    for level in (1.0, 2.5, 3.9, 9.0):
        brute = [np.flatnonzero(s >= level)[0] if (s >= level).any() else np.inf for s in scores]
        np.testing.assert_array_equal(curves.first(level), brute)


# ---- the C8 measure ------------------------------------------------------------------------------------------------
def _final_poi(world, genomes, ic):
    """Brute force: the POI each rover observes at the end, (E, N), -1 for none."""
    final = world.rollout(genomes, ic).xy[:, -1]                          # (E, N, 2)
    d = np.linalg.norm(final[:, :, None] - world.poi_xy[None, None], axis=-1)
    inside = d <= world.obs_radius
    return np.where(inside.any(axis=-1), inside.argmax(axis=-1), -1)


class _Recording(Evaluator):
    """The run's evaluator, keeping every team it measures (no kernel inputs: the Python loop runs)."""

    def __init__(self, inner, teams):
        self.inner, self.teams = inner, teams

    def measure(self, genomes):
        self.teams.append(genomes.copy())
        return self.inner.measure(genomes)

    def rollout(self, genomes):
        return self.inner.rollout(genomes)


@pytest.mark.parametrize("overrides", [["k=1"], ["k=2"], ["k=adaptive"], ["team=homogeneous"]])
def test_switched_counts_episodes_where_unmutated_rovers_change_poi(overrides):
    cfg = make_cfg("setup=duo", "generations=120", *overrides)
    run = Run(cfg, 5)
    parent_genomes = run.team.copy()
    teams = []
    run.evaluate = _Recording(run.evaluate, teams)
    h = run.advance(120)
    world = run.parts.world
    parent = _final_poi(world, parent_genomes, run.ic)
    for g, child_genomes in enumerate(teams):
        mutated = (child_genomes != parent_genomes).any(axis=1)
        child = _final_poi(world, child_genomes, run.ic)
        expected = -1 if mutated.all() else int((child[:, ~mutated] != parent[:, ~mutated]).any(axis=1).sum())
        assert h["switched"][g] == expected, g
        if h["accepted"][g]:
            parent, parent_genomes = child, child_genomes
    assert (h["switched"] >= 0).any() == ("team=homogeneous" not in overrides)


# ---- the whole pipeline on a tiny budget -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """launchers/paper.sh at 300 generations x 2 seeds, serially: the sweep, its results, figures and claims (the
    launcher's own figures; the per-sweep callback's are tested in test_plot)."""
    tmp = tmp_path_factory.mktemp("study")
    env = {**os.environ, "GENERATIONS": "300", "SEEDS": "2", "OUT": str(tmp / "sweep"),
           "RESULTS": str(tmp / "results"), "PYTHON": sys.executable}
    proc = subprocess.run(["bash", str(ROOT / "launchers" / "paper.sh"), "parallel=serial", NO_SWEEP_FIGURES],
                          cwd=tmp, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return tmp, env, proc


@pytest.mark.slow
def test_paper_launcher_writes_compact_results_figures_and_claims(study):
    tmp, _, proc = study
    sweep, results = tmp / "sweep", tmp / "results"
    jobs = sorted(p.name for p in sweep.iterdir() if (p / "summary.json").is_file())
    assert len(jobs) == 13                                                # Figs. 4, 5 (4 each), 7 (3), 8 (2)
    assert "generations=300,k=1,selection=strict,setup=duo" in jobs and "generations=300,k=1,setup=duo" in jobs
    assert sorted(p.parent.name for p in results.glob("*/curves.npz")) == jobs
    size = sum(f.stat().st_size for f in results.rglob("*") if f.is_file())
    assert size < 2_000_000
    compute = json.loads((results / "compute.json").read_text())
    assert compute["team_evals"] == 13 * 2 * 301 and compute["wall_time_s"] > 0
    index = json.loads((results / "figures" / "index.json").read_text())
    names = {f["name"] for f in index["figures"]}
    assert {"curves_solo", "curves_duo", "soft_vs_strict_duo", "bandit_solo", "bandit_duo", "fig6_duo",
            "switched_k1"} <= names
    text = (results / "claims.md").read_text()
    assert text in proc.stdout
    for section in ("C1-C3", "C4-C6", "C7", "C8", "Compute"):
        assert f"### {section}" in text
    data = json.loads((results / "claims.json").read_text())
    assert set(data["tables"]) == {"solo", "duo"} and len(data["tables"]["duo"]) == 8
    assert {"solo k=1", "duo k=1", "duo k=1 strict"} <= set(data["C8"])


@pytest.mark.slow
def test_exported_curves_equal_the_sweep(study):
    tmp, _, _ = study
    job = "generations=300,k=adaptive,setup=duo"
    with np.load(tmp / "results" / job / "curves.npz") as z:
        curves = Curves(z["seed"], int(z["generations"]), z["step_run"], z["step_generation"], z["step_score"])
        grid, score, probs = z["grid"], z["score"], z["probs"]
    for i, seed in enumerate(curves.seeds):
        with np.load(tmp / "sweep" / job / "runs" / f"seed_{seed:03d}" / "curve.npz") as full:
            np.testing.assert_array_equal(curves.full(i), full["score"])
            np.testing.assert_array_equal(score[i], full["score"][grid])
            np.testing.assert_allclose(probs[i], full["probs"][np.minimum(grid, 299)], rtol=1e-6)


@pytest.mark.slow
def test_relaunch_recomputes_only_the_unfinished_run(study):
    tmp, env, _ = study
    job = tmp / "sweep" / "generations=300,k=2,selection=strict,setup=duo"
    runs = sorted((job / "runs").iterdir())
    before = {r.name: (r / "run.json").stat().st_mtime_ns for r in runs}
    kept = np.load(runs[1] / "curve.npz")["score"]
    shutil.rmtree(runs[1])                                                # as if the launch died during this run
    proc = subprocess.run(["bash", str(ROOT / "launchers" / "fig7.sh"), "parallel=serial"], cwd=tmp, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    log = proc.stdout + proc.stderr
    assert log.count("2 of 2 runs already finished, skipped") == 2                  # k=1 and k=4 strict
    assert "1 of 2 runs already finished, skipped" in log
    after = {r.name: (r / "run.json").stat().st_mtime_ns for r in sorted((job / "runs").iterdir())}
    assert after[runs[0].name] == before[runs[0].name] and after[runs[1].name] != before[runs[1].name]
    np.testing.assert_array_equal(np.load(runs[1] / "curve.npz")["score"], kept)


def test_analysis_cli_bad_input_is_one_line(tmp_path):
    for args in (["selectors", str(tmp_path / "missing")], ["export", str(tmp_path), str(tmp_path / "out")],
                 ["claims", str(tmp_path)], ["nonsense"]):
        proc = run_cli(*args, module="rovermarl.analysis")
        assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
        assert proc.stderr.startswith("rovermarl.analysis")
    assert not (tmp_path / "out").exists()


# ---- Fig. 6 data: the updates are replayed, and each changed one rover -------------------------------------------
def test_fig6_export_replays_single_rover_updates(tmp_path):
    cfg = make_cfg("setup=duo", "generations=400", "seeds=1", "parallel=serial", "record.rerun=false")
    run_job(cfg, tmp_path / "job")
    (job,), _ = find_jobs(tmp_path / "job")
    info = export_fig6(job, tmp_path / "fig6.npz", levels=(1.0, 2.0))    # first reaching 1, then 2
    with np.load(tmp_path / "fig6.npz") as z:
        assert z["event_xy"].shape == (len(info["events"]), 2, 16, 16, 4, 2) and len(info["events"]) == 2
        assert np.all(z["event_score"][:, 0] < [1.0, 2.0]) and np.all(z["event_score"][:, 1] >= [1.0, 2.0])
        assert set(z["event_mutated"].tolist()) <= {0, 1, 2, 3}           # k=1: exactly one rover changed
        assert z["occupancy"].shape[1] == 10


# ---- the committed report --------------------------------------------------------------------------------------
RESULTS = ROOT / "results" / "paper"


def test_reproduction_report_quotes_the_committed_results(tmp_path):
    shutil.copytree(RESULTS, tmp_path / "paper", ignore=shutil.ignore_patterns("figures"))
    text, _ = study_module("paper").claims(tmp_path / "paper")           # recomputed from the committed results
    assert text == (RESULTS / "claims.md").read_text()
    assert text in (ROOT / "docs" / "REPRODUCTION.md").read_text()


@pytest.mark.parametrize("keep,missing", [
    ("setup=duo", "every solo job (k=1, k=2, k=4, homogeneous, adaptive)"),
    ("setup=solo", "every duo job (k=1, k=2, k=4, homogeneous, adaptive, k=1 strict, k=2 strict, k=4 strict)"),
    ("k=", "solo homogeneous; duo homogeneous"),                           # a method missing in both setups
])
def test_claims_on_a_partial_results_dir_names_what_is_missing_in_one_line(tmp_path, keep, missing):
    partial = tmp_path / "partial"
    for job in sorted(RESULTS.glob("*/curves.npz")):
        if keep in job.parent.name:
            shutil.copytree(job.parent, partial / job.parent.name)
    proc = run_study("paper", str(partial), timeout=300)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.endswith("\n") and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert proc.stderr == (f"studies/paper/report.py: error: {partial}: the claims report needs the 13 jobs of the "
                           f"paper study (launchers/paper.sh); missing: {missing}\n")
    assert proc.stdout == "" and not (partial / "claims.md").exists() and not (partial / "claims.json").exists()


# ---- the k-selector benchmark ----------------------------------------------------------------------------------
@pytest.mark.slow
def test_selectors_launcher_runs_every_selector_and_writes_the_table(tmp_path):
    env = {**os.environ, "GENERATIONS": "40", "SEEDS": "2", "OUT": str(tmp_path / "sweep"),
           "RESULTS": str(tmp_path / "results"), "PYTHON": sys.executable, "FIGURES": "no"}   # paper.sh's test draws
    proc = subprocess.run(["bash", str(ROOT / "launchers" / "selectors.sh"), "parallel=serial", "record=off",
                           NO_SWEEP_FIGURES],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    text = (tmp_path / "results" / "selectors.md").read_text()
    methods = ["k=1", "k=2", "k=3", "k=4", "homogeneous", "adaptive", "ucb1", "thompson", "egreedy", "exp3s",
               "schedule"]
    for setup in ("solo", "duo", "trio"):
        section = text.split(f"### {setup}\n")[1].split("###")[0]
        rows = [line.split(" | ")[0].lstrip("| ") for line in section.splitlines() if line.startswith("| ")][1:]
        assert rows == methods, setup
    assert "final score vs adaptive" in text and text in proc.stdout


SELECTOR_RESULTS = ROOT / "results" / "selectors"


def test_selectors_report_quotes_the_committed_results(tmp_path):
    from rovermarl.analysis.claims import selectors
    shutil.copytree(SELECTOR_RESULTS, tmp_path / "sel", ignore=shutil.ignore_patterns("figures"))
    text, _ = selectors(tmp_path / "sel")
    assert text == (SELECTOR_RESULTS / "selectors.md").read_text()
    assert text in (ROOT / "docs" / "SELECTORS.md").read_text()
