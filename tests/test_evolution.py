"""Mutation, selection, EXP3, teams and the generation loop (SPEC section 6)."""

import math

import numpy as np
import pytest

from rovermarl.algorithms import AlgorithmError
from rovermarl.algorithms.operators.mutation import MixedMutation
from rovermarl.algorithms.operators.selection import Selection
from rovermarl.algorithms.operators.selectors import EXP3, FixedK
from rovermarl.algorithms.operators.team import HeterogeneousTeam, HomogeneousTeam
from rovermarl.errors import ConfigError
from rovermarl.runner import Run
from tests.conftest import make_cfg


def test_mutation_statistics():
    op = MixedMutation()
    rng = np.random.default_rng(0)
    parent = np.zeros(658)
    n, gaussian, deltas = 3000, 0, []
    for _ in range(n):
        child = op(parent, rng)
        changed = np.count_nonzero(child != parent)
        if changed == 658:
            gaussian += 1
            deltas.append(child)
        else:
            assert changed == 164 == op.n_reset(658)             # floor(0.25 * 658) distinct resets
            assert np.abs(child).max() <= 2.0
    assert gaussian / n == pytest.approx(0.2, abs=0.03)          # 5 binomial sd
    assert np.std(np.concatenate(deltas)) == pytest.approx(0.1, rel=0.02)
    assert not np.shares_memory(op(parent, rng), parent)


def test_mutation_uniform_values_cover_the_range():
    op = MixedMutation(p_gaussian=0.0)
    child = op(np.full(658, 100.0), np.random.default_rng(1))
    reset = child[child != 100.0]
    assert reset.size == 164 and reset.min() >= -2 and reset.max() <= 2 and reset.std() > 0.9


@pytest.mark.parametrize("kwargs, key", [({"sigma": -1}, "sigma"), ({"p_gaussian": 1.5}, "p_gaussian"),
                                         ({"low": 2, "high": 1}, "high")])
def test_mutation_rejects_bad_values(kwargs, key):
    with pytest.raises(ConfigError, match=f"^{key}="):
        MixedMutation(**kwargs)


def test_soft_and_strict_on_ties():
    soft, strict = Selection(strict=False), Selection(strict=True)
    assert soft(2.0, 2.0) and not strict(2.0, 2.0)
    assert soft(2.5, 2.0) and strict(2.5, 2.0)
    assert not soft(1.5, 2.0) and not strict(1.5, 2.0)


@pytest.mark.parametrize("selection", ["soft", "strict"])
def test_loop_applies_the_selection_rule(selection):
    run = Run(make_cfg(f"selection={selection}", "k=2", "generations=400"), seed=3)
    h = run.advance(400)
    score = np.concatenate([[run.initial_score], h["score"]])
    prev = score[:-1]
    expected = h["child_score"] >= prev if selection == "soft" else h["child_score"] > prev
    np.testing.assert_array_equal(h["accepted"], expected)
    assert np.any(h["child_score"] == prev)                      # ties happen and were decided
    np.testing.assert_array_equal(score[1:], np.where(h["accepted"], h["child_score"], prev))
    assert np.all(np.diff(score) >= 0)


def test_exp3_probabilities_and_update_by_hand():
    b = EXP3(n_agents=4, gamma=0.1)
    assert b.arms == (1, 2, 3, 4)
    np.testing.assert_allclose(b.probs, 0.25)
    b.update(2, f_child=3.0, f_parent=2.0)                       # improved: x = 1, p = 0.25
    w = np.array([1, math.exp(0.1 * (1 / 0.25) / 4), 1, 1])
    np.testing.assert_allclose(b.probs, 0.9 * w / w.sum() + 0.1 / 4)
    before = b.probs.copy()
    b.update(3, f_child=2.0, f_parent=2.0)                       # tie is not an improvement: x = 0
    np.testing.assert_allclose(b.probs, before)


def test_exp3_gain_reward():
    b = EXP3(n_agents=4, gamma=0.2, reward="gain", f_max=4.0)
    b.update(1, f_child=3.0, f_parent=2.0)                       # x = 1/4
    w = np.array([math.exp(0.2 * (0.25 / 0.25) / 4), 1, 1, 1])
    np.testing.assert_allclose(b.probs, 0.8 * w / w.sum() + 0.2 / 4)


def test_exp3_concentrates_on_the_best_arm_and_never_overflows():
    b = EXP3(n_agents=4, gamma=0.1)
    rng, env = np.random.default_rng(0), np.random.default_rng(1)
    success = {1: 0.1, 2: 0.1, 3: 0.6, 4: 0.1}
    pulls = []
    for _ in range(3000):
        k = b.choose(rng)
        pulls.append(k)
        b.update(k, float(env.random() < success[k]), 0.0)
    assert np.all(np.isfinite(b.log_w)) and b.probs.sum() == pytest.approx(1.0)
    assert np.argmax(b.probs) == 2 and b.probs[2] > 0.8
    assert np.mean(np.array(pulls[-500:]) == 3) > 0.75
    assert b.probs.min() >= 0.1 / 4 - 1e-12                      # gamma keeps every arm alive


def test_exp3_rejects_bad_values():
    with pytest.raises(ConfigError, match="^gamma=0"):
        EXP3(n_agents=4, gamma=0)
    with pytest.raises(ConfigError, match=r"^arms=\[1, 5\]"):
        EXP3(n_agents=4, arms=[1, 5])
    with pytest.raises(ConfigError, match="^value=5"):
        FixedK(5, n_agents=4)


def test_teams_pick_and_clone():
    rng = np.random.default_rng(0)
    het = HeterogeneousTeam(4)
    for k in (1, 2, 4):
        chosen = het.pick(k, rng)
        assert len(set(chosen.tolist())) == k and set(chosen.tolist()) <= {0, 1, 2, 3}
    counts = np.bincount(np.concatenate([het.pick(1, rng) for _ in range(4000)]), minlength=4)
    assert counts.min() > 900                                    # uniform over rovers
    hom = HomogeneousTeam(4)
    parents = hom.init(658, -2, 2, rng)
    assert parents.shape == (1, 658)
    genomes = hom.genomes(parents)
    assert genomes.shape == (4, 658) and np.all(genomes == parents[0])
    children = hom.mutate(parents, hom.pick(3, rng), MixedMutation(), rng)
    assert not np.array_equal(children, parents)


def test_heterogeneous_loop_mutates_exactly_k_rovers():
    run = Run(make_cfg("k=2", "generations=50"), seed=0)
    for _ in range(50):
        before = run.team.copy()
        h = run.advance(1)
        changed = np.any(run.team != before, axis=1).sum()
        assert changed == (2 if h["accepted"][0] else 0)


def test_same_seed_same_curve_and_seeds_differ():
    runs = [Run(make_cfg("k=adaptive", "setup=duo", "generations=300"), seed=s) for s in (5, 5, 6)]
    hist = []
    for r in runs:
        first, rest = r.advance(120), r.advance(1000)            # stops at generations
        hist.append({key: np.concatenate([first[key], rest[key]]) for key in first})
    a, b, c = hist
    assert runs[0].done and runs[0].generation == 300
    for key, arr in a.items():
        np.testing.assert_array_equal(arr, b[key])
    assert not np.array_equal(a["child_score"], c["child_score"])
    assert a["probs"].shape == (300, 4) and np.allclose(a["probs"].sum(1), 1)
    assert set(np.unique(a["k"])) <= {1, 2, 3, 4}


class SevenK(FixedK):
    """A broken selector: it declares arm 1 but chooses 7."""

    def choose(self, rng):
        return 7


def test_a_selector_choosing_outside_its_arms_stops_the_run():
    cfg = make_cfg("k=1", "generations=5")
    cfg.k._target_ = f"{__name__}.SevenK"
    want = rf"^k-selector {__name__}.SevenK \(.*test_evolution\.py\) chose k=7; allowed: 1 "
    with pytest.raises(AlgorithmError, match=want):
        Run(cfg, seed=0).advance(5)


def test_it_learns():
    """k=1 on solo climbs well above a random team within 2,000 generations."""
    finals, starts = [], []
    for seed in range(3):
        run = Run(make_cfg("generations=2000"), seed=seed)
        run.advance(2000)
        starts.append(run.initial_score)
        finals.append(run.score)
    assert np.median(finals) >= 2.0
    assert min(f - s for f, s in zip(finals, starts, strict=True)) >= 1.0
