"""The optimisers' API: World.evaluate_many scores a population in one compiled call, each score the float
World.evaluate gives; World.homogeneous tiles one genome; a team whose genomes are not finite is warned about in one
line (it would score 0 silently); the CMA-ES example optimises a team through it."""

import sys
import warnings

import numpy as np
import pytest

from rovermarl.env import make_world
from tests.conftest import ROOT


@pytest.mark.parametrize("overrides", [{}, {"dtype": "float32"}, {"reward": "mean_step"}])
def test_evaluate_many_is_a_loop_of_evaluate_bit_for_bit(overrides):
    world = make_world("duo", **overrides)
    teams = np.random.default_rng(2).uniform(-2, 2, (9, world.n_rovers, world.n_params))
    teams[3] = world.homogeneous(teams[3, 0])
    ic = world.run_ic(5)
    many = world.evaluate_many(teams, ic)
    assert many.shape == (9,)
    assert [float(s) for s in many] == [world.evaluate(t, ic) for t in teams]
    with pytest.raises(ValueError, match=r"teams must have shape \(B, 4, 658\)"):
        world.evaluate_many(teams[0], ic)


def test_homogeneous_tiles_one_genome():
    world = make_world("solo")
    g = np.arange(world.n_params, dtype=float)
    team = world.homogeneous(g)
    assert team.shape == (4, world.n_params) and (team == g).all() and team.flags.c_contiguous
    with pytest.raises(ValueError, match="genome must have shape"):
        world.homogeneous(g[:-1])


@pytest.mark.parametrize("bad", [np.nan, np.inf, 1e300])
def test_a_team_that_is_not_finite_is_warned_about_in_one_line(bad):
    world = make_world("solo")
    team = np.zeros((4, world.n_params))
    team[2, 5] = bad
    with pytest.warns(RuntimeWarning, match="nan, inf or magnitudes") as record:
        assert world.evaluate(team, world.run_ic(0)) == 0.0
    assert "\n" not in str(record[0].message)
    with pytest.warns(RuntimeWarning, match="team 1's"):
        world.evaluate_many(np.stack([np.zeros_like(team), team]), world.run_ic(0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        world.evaluate(np.zeros((4, world.n_params)), world.run_ic(0))   # a finite team: no warning


def test_the_cma_example_optimises_a_team():
    pytest.importorskip("cma")
    sys.path.insert(0, str(ROOT / "examples" / "cma_team"))
    try:
        from cma_team import optimise
    finally:
        sys.path.pop(0)
    out = optimise("solo", evaluations=1500, seed=0)
    assert out["evaluations"] >= 1500 and out["best_score"] >= 1.0        # a zero or random team scores ~0
    assert 0 <= out["heldout_score"] <= 4


def test_read_only_inputs_reuse_the_compiled_rollout():
    """Arrays that Ray delivers are read-only; numba would compile the rollout again for them (20 s per worker)."""
    world = make_world("solo")
    ic = world.initial_conditions(seed=0, n=world.episodes)
    team = np.random.default_rng(0).normal(size=(world.n_rovers, world.n_params))
    want = world.evaluate(team, ic), world.evaluate_many(team[None], ic)
    compiled = world.compiled.rollout, world.compiled.evaluate, world.compiled.evaluate_many
    before = [len(f.signatures) for f in compiled]
    frozen = [a.copy() for a in (team, ic[0], ic[1])]
    for a in frozen:
        a.flags.writeable = False
    ic_frozen = type(ic)(frozen[1], frozen[2], *ic[2:])
    assert world.evaluate(frozen[0], ic_frozen) == want[0]
    assert world.evaluate_many(frozen[0][None], ic_frozen) == want[1]
    assert [len(f.signatures) for f in compiled] == before
