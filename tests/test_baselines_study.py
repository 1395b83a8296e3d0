"""The baselines study: launchers/baselines.sh at a tiny budget (equal team evaluations for cc11es and ccea, the
report's table, figures against team evaluations), and docs/BASELINES.md against the committed results."""

import json
import os
import re
import subprocess
import sys

import pytest

from tests.conftest import ROOT, study_module

baselines = study_module("baselines")

COMMITTED = ROOT / "results" / "baselines"
DOC = ROOT / "docs" / "BASELINES.md"
BLOCK = re.compile(r"<!-- baselines:begin -->\n(.*?)<!-- baselines:end -->", re.S)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("baselines")
    env = {**os.environ, "PYTHON": sys.executable, "EVALS": "111", "SEEDS": "2", "SETUPS": "duo",
           "OUT": str(tmp / "sweep"), "RESULTS": str(tmp / "results")}
    proc = subprocess.run(["bash", "launchers/baselines.sh", "parallel=serial"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return tmp


@pytest.mark.slow
def test_every_method_gets_the_same_budget_of_team_evaluations(study):
    jobs = json.loads((study / "results" / "baselines.json").read_text())["jobs"]
    assert [j["method"] for j in jobs] == ["k=1", "k=2", "adaptive", "ccea G", "ccea D", "ccea D++"]
    for j in jobs:
        ccea = j["method"].startswith("ccea")
        assert j["evals_per_generation"] == (11 if ccea else 1)
        assert j["generations"] == (10 if ccea else 111)              # ceil((111 - 1) / 11) = 10
        assert j["team_evals_per_run"] == 111 if ccea else 112       # the initial team's evaluation included
        assert len(j["runs"]) == 2 and j["compute"]["team_evals"] >= 2 * j["team_evals_per_run"]
        for run in j["runs"].values():
            for evals in run["evals_to"].values():
                assert evals is None or (evals - 1) % j["evals_per_generation"] == 0


@pytest.mark.slow
def test_the_report_has_a_row_per_method_and_tests_against_k1(study):
    text, numbers = baselines.report(study / "results")
    rows = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) == 1 + 6 and "vs k=1" in rows[0] and "evals to 6" in rows[0]
    assert rows[1].split("|")[-3].strip() == "-"                          # k=1 is not tested against itself
    assert all("P(a>b)=" in r for r in rows[2:])
    assert (study / "results" / "baselines.md").read_text() == text


@pytest.mark.slow
def test_the_figures_put_team_evaluations_on_the_x_axis(study):
    last = json.loads((study / "sweep" / "figures" / "index.json").read_text())   # the last launch's callback
    assert {m for f in last["figures"] for m in f.get("methods", ())} == {"ccea D++"}  # reads only its own jobs
    proc = subprocess.run([sys.executable, "-m", "rovermarl.plot", str(study / "sweep"), "--out",
                           str(study / "all")], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    index = json.loads((study / "all" / "index.json").read_text())              # the whole sweep, drawn by plot
    curves = [f for f in index["figures"] if f["kind"] == "curves"]
    assert curves and all(f["x"] == "evals" for f in curves)
    assert {"ccea G", "ccea D", "ccea D++", "k=1"} <= set(curves[0]["methods"])
    assert (study / "all" / "curves_duo.png").is_file()
    jobs = json.loads((study / "results" / "baselines.json").read_text())["jobs"]   # the launcher's, from the json
    for j in jobs:
        assert j["curve"]["evals"][0] == 1 and j["curve"]["evals"][-1] == j["team_evals_per_run"]
        assert len(j["curve"]["evals"]) == len(j["curve"]["median"]) > 10
        assert all(a <= m <= b for a, m, b in zip(j["curve"]["q1"], j["curve"]["median"], j["curve"]["q3"],
                                                  strict=True))
    assert (study / "results" / "figures" / "baselines_duo.png").stat().st_size > 10_000


@pytest.mark.slow
def test_a_study_resumes_from_its_committed_results_without_its_sweep_dir(study, tmp_path):
    """A new session has the committed results but not outputs/: the jobs there are skipped, the others run, and
    the report then holds both."""
    results = tmp_path / "results"
    results.mkdir()
    data = json.loads((study / "results" / "baselines.json").read_text())
    data["jobs"] = [j for j in data["jobs"] if j["method"] != "ccea D"]           # as if ccea D had not finished
    (results / "baselines.json").write_text(json.dumps(data))
    env = {**os.environ, "PYTHON": sys.executable, "EVALS": "111", "SEEDS": "2", "SETUPS": "duo",
           "OUT": str(tmp_path / "sweep"), "RESULTS": str(results), "FIGURES": "no"}
    proc = subprocess.run(["bash", "launchers/baselines.sh", "parallel=serial"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stderr.count("baselines.json: skipped") == 5
    assert [p.name for p in (tmp_path / "sweep").iterdir() if (p / "summary.json").is_file()] == [
        next(j["job"] for j in json.loads((study / "results" / "baselines.json").read_text())["jobs"]
             if j["method"] == "ccea D")]
    again = json.loads((results / "baselines.json").read_text())["jobs"]
    before = json.loads((study / "results" / "baselines.json").read_text())["jobs"]
    assert [j["method"] for j in again] == [j["method"] for j in before]
    assert [j["runs"] for j in again] == [j["runs"] for j in before]                 # the same numbers, rerun
    assert "In progress: 6 of 18 jobs; to come: k=1 on solo," in baselines.report(results)[0]   # duo is whole


@pytest.mark.slow
def test_a_sweep_at_another_budget_does_not_join_the_results(study, tmp_path):
    data = json.loads((study / "results" / "baselines.json").read_text())
    data["jobs"] = [j for j in data["jobs"] if j["method"] != "k=1"]
    for j in data["jobs"]:                                                          # other jobs, at three seeds
        j["setup"], j["runs"]["2"] = "solo", j["runs"]["0"]
    (tmp_path / "baselines.json").write_text(json.dumps(data))
    with pytest.raises(baselines.ResultsError, match="k=2 on solo has 3 seeds at 112 team evaluations per run, "
                                                     "k=1 on duo has 2 at 112: another budget"):
        baselines.export(study / "sweep", tmp_path, log=lambda m: None)
    assert json.loads((tmp_path / "baselines.json").read_text()) == data            # left as it was


@pytest.mark.slow
def test_a_partial_study_says_which_jobs_are_to_come(study, tmp_path):
    data = json.loads((study / "results" / "baselines.json").read_text())
    (tmp_path / "baselines.json").write_text(json.dumps(data))
    text, _ = baselines.report(tmp_path)
    assert "In progress: 6 of 18 jobs; to come: k=1 on solo, k=2 on solo," in text and "ccea D++ on trio." in text


@pytest.mark.slow
def test_the_method_comparison_measures_in_team_evaluations(study):
    from rovermarl.analysis.claims import selectors
    from rovermarl.analysis.export import export
    export(study / "sweep", study / "exported", fig6=False, log=lambda m: None)
    text, data = selectors(study / "exported", against="k=1", x="evals")
    assert text.startswith("Budget: 112 team evaluations per run; scores at 1, 11, 112 team evaluations")
    assert "median team evaluations to 5" in text and "team evaluations to 5 vs k=1" in text
    rows = data["tables"]["duo"]
    assert set(rows) == {"k=1", "k=2", "adaptive", "ccea G", "ccea D", "ccea D++"}
    generations, _ = selectors(study / "exported", against="k=1")
    assert generations.startswith("Budget: 111 generations per run")


def test_the_doc_table_is_the_committed_results_report():
    block = BLOCK.search(DOC.read_text())
    if not (COMMITTED / "baselines.json").is_file():                # the study has not been committed yet
        assert block is None and "not yet run" in DOC.read_text()
        return
    assert block is not None, "docs/BASELINES.md has no <!-- baselines:begin/end --> block"
    text, _ = baselines.report(COMMITTED)
    assert block.group(1) == text
