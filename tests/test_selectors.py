"""The k-selector family, each on a toy reward stream for its defining behaviour, and resumable mid-stream."""

import numpy as np
import pytest

from rovermarl.algorithms.operators.selectors import EXP3, EXP3S, UCB1, EpsilonGreedy, Schedule, Thompson
from rovermarl.config import compose_config
from rovermarl.errors import ConfigError
from rovermarl.runner import build

P_IMPROVE = np.array([0.05, 0.30, 0.10, 0.02])  # arm k=2 improves the team most often


def play(selector, steps: int, p=P_IMPROVE, seed: int = 0, switch_at: int | None = None, p_after=None):
    """Feed ``selector`` a Bernoulli "improved" stream (k -> P(improved)); returns the k chosen each step."""
    rng_sel, rng_env = np.random.default_rng(seed), np.random.default_rng(seed + 1)
    chosen = np.empty(steps, dtype=np.int64)
    for t in range(steps):
        probs = p if switch_at is None or t < switch_at else p_after
        k = selector.choose(rng_sel)
        improved = rng_env.random() < probs[selector.arms.index(k)]
        selector.update(k, 1.0 if improved else 0.0, 0.0)
        chosen[t] = k
    return chosen


def test_ucb1_tries_every_arm_first_then_exploits():
    ucb = UCB1(n_agents=4)
    chosen = play(ucb, 3000)
    assert list(chosen[:4]) == [1, 2, 3, 4]
    assert np.mean(chosen[-1000:] == 2) > 0.7
    assert ucb.counts.sum() == 3000 and ucb.counts.min() >= 1


def test_thompson_posterior_counts_and_concentration():
    ts = Thompson(n_agents=4)
    chosen = play(ts, 3000)
    assert ts.alpha.sum() + ts.beta.sum() == 3000 + 8                    # one observation per step + the priors
    assert np.mean(chosen[-1000:] == 2) > 0.8


@pytest.mark.parametrize("epsilon", [0.0, 0.2])
def test_epsilon_greedy_explores_at_rate_epsilon(epsilon):
    eg = EpsilonGreedy(n_agents=4, epsilon=epsilon)
    chosen = play(eg, 4000)
    probs = eg.probs
    assert probs.sum() == pytest.approx(1) and probs.min() == pytest.approx(epsilon / 4)
    share = np.mean(chosen[-2000:] == 2)
    assert share == pytest.approx(1 - epsilon + epsilon / 4, abs=0.05)


def test_exp3s_tracks_a_best_k_that_changes_and_exp3_lags():
    after = np.array([0.02, 0.05, 0.10, 0.30])                            # k=4 becomes the best at step 4000
    s, plain = EXP3S(n_agents=4, alpha=0.001), EXP3(n_agents=4)
    chosen_s = play(s, 8000, switch_at=4000, p_after=after)
    chosen_e = play(plain, 8000, switch_at=4000, p_after=after)
    assert np.mean(chosen_s[3000:4000] == 2) > 0.5 and np.mean(chosen_e[3000:4000] == 2) > 0.5
    assert np.mean(chosen_s[-1000:] == 4) > 0.5
    assert np.mean(chosen_s[-1000:] == 4) > np.mean(chosen_e[-1000:] == 4) + 0.2
    assert np.all(np.isfinite(s.log_w)) and s.probs.sum() == pytest.approx(1)


def test_exp3s_with_alpha_zero_is_exp3():
    a, b = EXP3S(n_agents=4, alpha=0.0), EXP3(n_agents=4)
    np.testing.assert_array_equal(play(a, 500), play(b, 500))
    np.testing.assert_allclose(a.probs, b.probs, rtol=1e-12)


def test_schedule_steps_down_from_n_to_one_in_equal_stages():
    sched = Schedule(n_agents=4, horizon=1000)
    chosen = play(sched, 1200)
    assert list(chosen[[0, 249, 250, 499, 500, 749, 750, 999, 1000, 1199]]) == [4, 4, 3, 3, 2, 2, 1, 1, 1, 1]
    assert [np.sum(chosen[:1000] == k) for k in (1, 2, 3, 4)] == [250] * 4
    assert sched.arms == (1, 2, 3, 4)
    assert list(play(Schedule(n_agents=4, horizon=6, start=3, end=2), 6)) == [3, 3, 3, 2, 2, 2]


def test_schedule_horizon_defaults_to_the_budget():
    selector = build(compose_config("k=schedule", "generations=1234")).algorithm.selector
    assert selector.horizon == 1234 and selector.stages == (4, 3, 2, 1)


@pytest.mark.parametrize("option", ["adaptive", "ucb1", "thompson", "egreedy", "exp3s", "schedule"])
def test_selectors_resume_mid_stream(option):
    """state_dict / load_state_dict: a selector restored mid-stream continues exactly like the original."""
    make = lambda: build(compose_config(f"k={option}", "generations=600")).algorithm.selector  # noqa: E731
    a, b = make(), make()
    play(a, 300, seed=3)
    b.load_state_dict(a.state_dict())
    rng_a, rng_b = np.random.default_rng(9), np.random.default_rng(9)
    for t in range(300):
        ka, kb = a.choose(rng_a), b.choose(rng_b)
        assert ka == kb, t
        a.update(ka, float(t % 7 == 0), 0.0)
        b.update(kb, float(t % 7 == 0), 0.0)


@pytest.mark.parametrize("override, key", [
    (["k=ucb1", "k.c=-1"], "k.c"), (["k=thompson", "k.alpha=0"], "k.alpha"),
    (["k=egreedy", "k.epsilon=1.5"], "k.epsilon"), (["k=exp3s", "k.alpha=2"], "k.alpha"),
    (["k=schedule", "k.start=9"], "k.start"), (["k=schedule", "k.horizon=0"], "k.horizon"),
    (["k=ucb1", "k.arms=[1,5]"], "k.arms")])
def test_selectors_reject_bad_values_by_name(override, key):
    with pytest.raises(ConfigError) as err:
        build(compose_config(*override))
    assert str(err.value).startswith(key)
