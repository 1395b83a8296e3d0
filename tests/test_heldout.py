"""The held-out score: every finished run's final team scored on ``evaluation.heldout`` initial conditions of a
stream its algorithm never sees, in run.json and summary.json."""

import json

import numpy as np
import pytest

from rovermarl import make_world
from rovermarl.runner.job import run_job
from tests.conftest import make_cfg

QUICK = ("generations=20", "seeds=2", "parallel=serial", "record=off")


def test_a_world_where_every_poi_is_always_observed_scores_the_optimum_held_out(tmp_path):
    # obs_radius 100: every rover observes every POI wherever it goes, so any team scores 10 on any episode.
    summary = run_job(make_cfg(*QUICK, "env.obs_radius=100"), tmp_path)
    runs = [json.loads((tmp_path / f"runs/seed_{s:03d}/run.json").read_text()) for s in (0, 1)]
    assert [r["heldout_score"] for r in runs] == [10.0, 10.0]
    assert summary["heldout_score"] == {"0": 10.0, "1": 10.0} and summary["median_heldout_score"] == 10.0
    assert json.loads((tmp_path / "summary.json").read_text())["heldout_score"] == {"0": 10.0, "1": 10.0}


def test_heldout_is_the_final_team_on_its_own_initial_conditions(tmp_path):
    summary = run_job(make_cfg(*QUICK, "setup=duo", "k=2", "evaluation.heldout=64"), tmp_path)
    world = make_world("duo")
    for seed in (0, 1):
        out = tmp_path / f"runs/seed_{seed:03d}"
        ic = world.heldout_ic(seed, 64)
        assert ic[0].shape == (64, 4, 2)
        assert not np.isin(ic[0], world.run_ic(seed)[0]).any()                     # not the run's episodes
        want = world.evaluate(np.load(out / "genomes.npy"), ic)
        assert json.loads((out / "run.json").read_text())["heldout_score"] == want
        assert summary["heldout_score"][str(seed)] == want


def test_an_edited_run_json_is_recomputed_not_believed(tmp_path, caplog):
    cfg = make_cfg(*QUICK, "k=adaptive")
    first = run_job(cfg, tmp_path)
    path = tmp_path / "runs/seed_001/run.json"
    meta = json.loads(path.read_text())
    path.write_text(json.dumps({**meta, "heldout_score": 99.0}))          # edited by hand: its checksum fails
    (tmp_path / "summary.json").unlink()
    with caplog.at_level("WARNING", logger="rovermarl"):
        again = run_job(cfg, tmp_path)
    warned = [r.message for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) == 1 and "does not match its own checksum; recomputing the run" in warned[0]
    assert again["heldout_score"] == first["heldout_score"] and again["final_score"] == first["final_score"]
    assert json.loads(path.read_text())["heldout_score"] == meta["heldout_score"]


@pytest.mark.parametrize("over", [(), ("evaluation.fresh_ic=true",)])
def test_heldout_follows_the_world_reading(tmp_path, over):
    summary = run_job(make_cfg(*QUICK, "setup=duo", "env.reward=mean_step", *over), tmp_path)
    genomes = np.load(tmp_path / "runs/seed_000/genomes.npy")
    mean_step, final = make_world("duo", reward="mean_step"), make_world("duo")
    got = summary["heldout_score"]["0"]
    assert got == mean_step.evaluate(genomes, mean_step.heldout_ic(0, 256)) > 0
    assert got != final.evaluate(genomes, final.heldout_ic(0, 256))
