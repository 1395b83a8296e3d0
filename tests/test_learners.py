"""The learners study's parts: one budget unit (agent-steps) for every learner, and CMA-ES over the whole team
(sep-CMA) resuming bit-identically."""

import numpy as np
import pytest

from rovermarl.config import compose_config
from rovermarl.env import make_world
from rovermarl.errors import ConfigError
from rovermarl.runner.chunk import advance, parts, to_plain
from rovermarl.runner.identity import config_hash
from rovermarl.runner.validate import validate
from tests.conftest import make_cfg, study_module


@pytest.mark.parametrize("algorithm,generations", [("cc11es", 20000), ("ccea", 1818), ("cma", 740)])
def test_agent_steps_set_generations_for_every_learner(algorithm, generations):
    cfg = compose_config(f"algorithm={algorithm}", "budget.agent_steps=19200000")
    validate(cfg)
    assert cfg.generations == generations
    algo = parts(to_plain(cfg)).algorithm
    assert algo.agent_steps_per_generation() == 960 * algo.evaluations_per_generation()
    assert algo.own_agent_steps_per_generation() == 0                  # its steps are all team evaluations


def test_no_agent_steps_leaves_generations_and_the_run_identity_as_they_were():
    cfg = compose_config("setup=duo", "generations=123")
    before = config_hash(to_plain(cfg))
    validate(cfg)
    assert cfg.generations == 123 and config_hash(to_plain(cfg)) == before
    assert "budget" not in to_plain(cfg)                  # null: the config reads as before the section existed


def test_a_budget_under_one_generation_is_refused_in_one_line():
    cfg = compose_config("budget.agent_steps=100")
    with pytest.raises(ConfigError, match="budget.agent_steps"):
        validate(cfg)


def test_cma_resumes_bit_identically_and_scores_its_best_team():
    plain = to_plain(make_cfg("algorithm=cma", "setup=duo", "generations=12", "record=off"))
    whole = advance(plain, 2, None, 12)
    first = advance(plain, 2, None, 5)
    rest = advance(plain, 2, first["state"], 12)
    assert np.array_equal(np.concatenate([first["score"], rest["score"]]), whole["score"])
    for name in ("team_evals", "sigma"):
        assert np.array_equal(np.concatenate([first["series"][name], rest["series"][name]]), whole["series"][name])
    assert whole["evaluations"] == 1 + 27 * 12 and whole["series"]["team_evals"][-1] == 1 + 27 * 12
    world = make_world("duo")
    assert world.evaluate(np.asarray(whole["genomes"]), world.run_ic(2)) == whole["score"][-1]
    assert np.all(np.diff(whole["score"]) >= 0)           # the best sample so far


def test_cma_learns_solo():
    plain = to_plain(make_cfg("algorithm=cma", "setup=solo", "generations=60", "record=off"))
    out = advance(plain, 0, None, 60)
    assert out["score"][-1] > out["initial_score"] + 0.5, (out["initial_score"], out["score"][-1])


def test_a_missing_rl_extra_is_named_in_one_line():
    import importlib.util
    if importlib.util.find_spec("torch") is not None:
        pytest.skip("torch is installed: the [rl] path runs in tests/test_sb3.py")
    with pytest.raises(ConfigError, match=r'pip install -e "\.\[rl\]"') as e:
        validate(compose_config("algorithm=ppo"))
    assert "\n" not in str(e.value)


def test_docs_learners_is_generated_from_the_committed_results():
    from pathlib import Path

    learners = study_module("learners")
    root = Path(__file__).resolve().parents[1]
    doc = (root / "docs" / "LEARNERS.md").read_text()
    assert learners.block(doc) == learners.report(root / "results" / "learners"), \
        "docs/LEARNERS.md is stale: python studies/learners/report.py results/learners"


def test_learner_cells_are_named_from_their_overrides_and_holm_adjusts():
    classify = study_module("learners").classify
    from rovermarl.analysis.stats import holm
    assert classify("budget.agent_steps=19200000,k=1,setup=solo") == ("solo", "cces_k1", "fixed")
    assert classify("algorithm.reward=dpp,algorithm=ccea,budget.agent_steps=1000,env=obstacles") == (
        "obstacles", "ccea_dpp", "fixed")
    assert classify("+algorithm.final_team=best,algorithm.reward=dpp,algorithm=ccea,budget.agent_steps=1000,"
                    "evaluation.fresh_ic=True,setup=duo") == ("duo", "ccea_dpp", "fresh")
    assert classify("budget.agent_steps=5,setup=duo,team=homogeneous") == ("duo", "cces_homogeneous", "fixed")
    assert classify("algorithm.reward=global,algorithm=ccea,budget.agent_steps=5,setup=duo") is None
    assert classify("k=1,setup=solo") is None                           # not a job of the study (no agent-steps)
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])


def test_the_median_interval_is_exact_and_seedless():
    """The order-statistic interval: its coverage from the binomial, the largest k that keeps it at 95%."""
    from scipy.stats import binom

    from rovermarl.analysis.stats import iqm, median_exact
    x = np.arange(16.0)[::-1]
    est, coverage = median_exact(x)
    assert (est.value, est.low, est.high) == (7.5, 3.0, 12.0)                  # k = 4: x_(4), x_(13)
    assert coverage == pytest.approx(1 - 2 * binom.cdf(3, 16, 0.5)) and coverage >= 0.95
    assert 1 - 2 * binom.cdf(4, 16, 0.5) < 0.95                                 # k = 5 would not keep 95%
    assert median_exact(np.arange(8.0))[0].low == 0.0                            # n = 8: the range (99.2%)
    assert iqm([0, 1, 2, 3, 4, 5, 6, 100]) == pytest.approx(3.5)


def test_the_learners_reading_is_the_datas():
    """Every sentence of the reading, re-derived here from results/learners with scipy alone: the leader is the
    highest held-out median, each U and Holm p is scipy's Mann-Whitney of held-out scores, Holm by hand."""
    import json
    from pathlib import Path

    from scipy.stats import mannwhitneyu

    learners = study_module("learners")
    root = Path(__file__).resolve().parents[1] / "results" / "learners"
    doc = learners.block((root.parents[1] / "docs" / "LEARNERS.md").read_text())
    found = {}
    for job in sorted(root.iterdir()):
        key = learners.classify(job.name)
        if key and (job / "summary.json").is_file():
            found[key] = np.array(list(json.loads((job / "summary.json").read_text())["heldout_score"].values()))
    for world, regime in {(w, r) for w, _, r in found}:
        row = {lr: found[(world, lr, regime)] for lr in learners.LEARNERS if (world, lr, regime) in found}
        if len(row) < 2:
            continue
        leader = max(row, key=lambda n: (np.median(row[n]), -list(row).index(n)))
        line = next(ln for ln in doc.splitlines() if ln.startswith(f"- **{world}, {learners.REGIMES[regime]}**"))
        assert f"{learners.LEARNERS[leader]} has the highest held-out median ({np.median(row[leader]):.3g})" in line
        others = [n for n in row if n != leader]
        p = [mannwhitneyu(row[leader], row[n], alternative="two-sided").pvalue for n in others]
        order, running, adjusted = np.argsort(p), 0.0, [0.0] * len(p)
        for rank, i in enumerate(order):
            running = max(running, min(1.0, (len(p) - rank) * p[i]))
            adjusted[i] = running
        for n, q in zip(others, adjusted, strict=True):
            shown = "<1e-4" if q < 1e-4 else f"={q:.2g}"
            assert f"{learners.LEARNERS[n]} (" in line and f"Holm p{shown})" in line.split(learners.LEARNERS[n])[1]
