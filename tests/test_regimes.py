"""The two training regimes of issue 54 (SPEC section 8) for every learner that is not CC-(1+1)-ES's own test's:
under evaluation.fresh_ic each generation scores on its own initial conditions, the kept team again beside the new
ones; ``final_team=best`` keeps the best team; both resume bit-identically; summary.json says which regime and rule."""

import json

import numpy as np
import pytest

from rovermarl.runner.chunk import advance, parts, to_plain
from rovermarl.runner.job import run_job
from tests.conftest import make_cfg

LEARNERS = {"ccea_dpp": ("algorithm=ccea", "algorithm.reward=dpp", "+algorithm.final_team=best"),
            "cma": ("algorithm=cma",)}


@pytest.mark.parametrize("fresh", [False, True], ids=["fixed", "fresh"])
@pytest.mark.parametrize("learner", sorted(LEARNERS))
def test_regimes_resume_bit_identically(learner, fresh):
    plain = to_plain(make_cfg(*LEARNERS[learner], "setup=duo", "generations=6", "record=off",
                              f"evaluation.fresh_ic={str(fresh).lower()}"))
    whole = advance(plain, 3, None, 6)
    first = advance(plain, 3, None, 2)
    rest = advance(plain, 3, first["state"], 6)
    assert np.array_equal(np.concatenate([first["score"], rest["score"]]), whole["score"])
    assert np.array_equal(rest["genomes"], whole["genomes"])
    algo = parts(plain).algorithm
    assert algo.final_team == "best"
    if not fresh:                                            # the same starts every generation: never lower
        assert np.all(np.diff(whole["score"]) >= 0)
    per = algo.evaluations_per_generation(fresh)
    assert whole["evaluations"] == 1 + 6 * per               # the kept team's re-scoring counted under fresh


def test_fresh_scores_move_with_the_generations_starts():
    """Under fresh_ic the CCEA's kept team is scored on new starts each generation: its score is not monotone in
    general, and differs from the fixed regime's curve."""
    over = ("algorithm=ccea", "+algorithm.final_team=best", "setup=solo", "generations=12", "record=off")
    fixed = advance(to_plain(make_cfg(*over)), 0, None, 12)["score"]
    fresh = advance(to_plain(make_cfg(*over, "evaluation.fresh_ic=true")), 0, None, 12)["score"]
    assert not np.array_equal(fixed, fresh)


def test_summary_says_the_regime_and_the_final_team_rule(tmp_path):
    run_job(make_cfg("generations=5", "seeds=1", "parallel=serial", "record=off", "evaluation.fresh_ic=true"),
            tmp_path / "a")
    run_job(make_cfg("algorithm=ccea", "generations=3", "seeds=1", "parallel=serial", "record=off"), tmp_path / "b")
    a = json.loads((tmp_path / "a" / "summary.json").read_text())
    b = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert (a["train_ic"], a["final_team"]) == ("fresh", "best")
    assert (b["train_ic"], b["final_team"]) == ("fixed", "last")


def test_a_relaunch_of_a_finished_budget_job_keeps_its_saved_generations(tmp_path):
    """Hydra rewrites .hydra/config.yaml at every launch, before budget.agent_steps sets generations (halved under
    fresh_ic for CC-(1+1)-ES): a relaunch that finds every run finished still writes the generations the runs have,
    so readers size the runs' files right."""
    from omegaconf import OmegaConf

    from tests.conftest import run_cli
    args = ("setup=solo", "budget.agent_steps=96000", "evaluation.fresh_ic=true", "seeds=1", "parallel=serial",
            "record=off", f"hydra.run.dir={tmp_path / 'job'}")
    for _ in range(2):                                                       # the launch, then the relaunch
        proc = run_cli(*args, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert OmegaConf.load(tmp_path / "job" / ".hydra" / "config.yaml").generations == 50   # 96000 / (2 x 960)
