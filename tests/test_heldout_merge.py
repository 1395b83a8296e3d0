"""studies/heldout/report.py merge: held-out scores of recomputed runs go into committed compact results only when
every run ends at the committed final score; then the curves' numbers stay and the held-out column is added."""

import json
import shutil

import pytest

from rovermarl.analysis.results import ResultsError
from rovermarl.analysis.verify import verify
from tests.conftest import run_cli, study_module

merge = study_module("heldout").merge


def test_merge_adds_held_out_scores_of_the_same_runs_only(tmp_path):
    name = "generations=40,k=2,setup=duo"
    proc = run_cli("k=2", "setup=duo", "generations=40", "seeds=2", "parallel=serial", "record=off",
                   f"hydra.run.dir='{tmp_path / 'sweep' / name}'")
    assert proc.returncode == 0, proc.stderr[-2000:]
    done = json.loads((tmp_path / "sweep" / name / "summary.json").read_text())
    committed = {k: v for k, v in done.items() if k not in ("heldout_score", "median_heldout_score")}
    (tmp_path / "results" / name).mkdir(parents=True)
    target = tmp_path / "results" / name / "summary.json"
    target.write_text(json.dumps(committed))
    shutil.copy(tmp_path / "sweep" / name / ".hydra" / "config.yaml", target.parent / "config.yaml")
    assert merge(tmp_path / "sweep", tmp_path / "results", log=lambda m: None) == [name]
    merged = json.loads(target.read_text())
    assert merged["heldout_score"] == done["heldout_score"] and merged["final_score"] == committed["final_score"]
    (checked,) = verify(tmp_path / "results")                       # the final teams came too, and re-score
    assert checked.ok and checked.line.startswith("2 teams re-score"), checked.line
    assert merge(tmp_path / "sweep", tmp_path / "results", log=lambda m: None) == []          # already there
    other = {**committed, "final_score": {**committed["final_score"], "1": committed["final_score"]["1"] + 0.0625}}
    target.write_text(json.dumps(other))
    (target.parent / "genomes.npz").unlink()
    with pytest.raises(ResultsError, match="seed 1 ends at"):
        merge(tmp_path / "sweep", tmp_path / "results", log=lambda m: None)
    assert "heldout_score" not in json.loads(target.read_text()) and not (target.parent / "genomes.npz").exists()
    shutil.rmtree(tmp_path / "sweep" / name / "runs" / "seed_001")
    (tmp_path / "sweep" / name / "summary.json").write_text(json.dumps({**done, "final_score": {"0": 1.0}}))
    target.write_text(json.dumps(committed))
    assert merge(tmp_path / "sweep", tmp_path / "results", log=lambda m: None) == []          # not all runs: skipped
