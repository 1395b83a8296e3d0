"""The World (compiled kernel) against tests/reference.py, the SPEC in plain numpy, on random scenes."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovermarl import make_world
from tests import reference

WORLDS = {"solo": make_world("solo"), "duo": make_world("duo")}

coord = st.floats(-40, 40, allow_nan=False)
angle = st.floats(-50, 50, allow_nan=False)


def test_reference_wrap_is_the_exact_remainder():
    a = np.concatenate([np.random.default_rng(0).uniform(-60, 60, 10_000), [math.pi, -math.pi, 3 * math.pi, 0.0]])
    want = np.array([math.remainder(x, 2 * math.pi) for x in a])     # exact reduction to [-pi, pi]
    want[want == math.pi] = -math.pi
    np.testing.assert_allclose(reference.wrap(a), want, rtol=0, atol=1e-13)
    assert np.all((reference.wrap(a) >= -math.pi) & (reference.wrap(a) < math.pi))


@settings(max_examples=150, deadline=None)
@given(setup=st.sampled_from(["solo", "duo"]), xy=st.lists(st.tuples(coord, coord), min_size=4, max_size=4),
       heading=st.lists(angle, min_size=4, max_size=4))
def test_observe_matches_reference(setup, xy, heading):
    world = WORLDS[setup]
    xy, heading = np.array(xy), np.array(heading)
    got = world.observe(xy, heading)
    want = reference.observe(world, xy[None], heading[None])[0]
    angles = np.zeros(got.shape[1], dtype=bool)
    angles[1:30:3] = angles[31::2] = True                  # bearing / pi columns
    np.testing.assert_allclose(got[:, ~angles], want[:, ~angles], rtol=1e-12, atol=1e-12)
    on_circle = (got[:, angles] - want[:, angles] + 1) % 2 - 1   # -pi and pi - ulp are neighbours
    np.testing.assert_allclose(on_circle, 0, atol=1e-12)
    assert np.all((got[:, angles] >= -1) & (got[:, angles] < 1))


@settings(max_examples=150, deadline=None)
@given(setup=st.sampled_from(["solo", "duo"]), seed=st.integers(0, 2**32 - 1),
       spread=st.floats(0, 3))
def test_team_return_matches_reference(setup, seed, spread):
    world = WORLDS[setup]
    rng = np.random.default_rng(seed)
    xy = world.poi_xy[rng.integers(0, world.n_pois, 4)] + rng.normal(0, spread, (4, 2))
    got = world.team_return(xy)
    assert got == reference.team_return(world, xy[None])[0]
    assert 0 <= got <= world.max_return


def test_observe_and_team_return_match_reference_far_out():
    world = make_world("duo")
    rng = np.random.default_rng(1)
    xy, heading = rng.uniform(-35, 35, (9, 4, 2)), rng.uniform(-20, 20, (9, 4))
    np.testing.assert_allclose(reference.observe(world, xy, heading), world.observe(xy, heading), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(reference.team_return(world, xy), world.team_return(xy))


ROLLOUT_WORLDS = [("solo", {}), ("duo", {}), ("duo", {"n_rovers": 3, "hidden": 5, "episodes": 5, "steps": 7}),
                  ("solo", {"n_rovers": 6, "hidden": 9, "episodes": 11, "coupling": [1, 2, 3],
                            "value": [1.0, 2.0, 4.0]}),
                  ("solo", {"n_rovers": 1, "hidden": 1, "episodes": 1, "steps": 1, "sensor_range": 12.5})]


@pytest.mark.parametrize("setup,overrides", ROLLOUT_WORLDS)
def test_rollout_matches_reference(setup, overrides):
    """Returns equal, trajectories within 1e-8 after all steps (rounding differences grow ~1e6-fold in 15 steps;
    the old scalar libm kernel and the reference also differ by up to ~4e-10)."""
    world = make_world(setup, **overrides)
    ic = world.initial_conditions(seed=3)
    rng = np.random.default_rng(7)
    for _ in range(6):
        genomes = rng.uniform(-2, 2, (world.n_rovers, world.n_params))
        roll = world.rollout(genomes, ic)
        xy, heading, returns = reference.rollout(world, genomes, ic, record=True)
        np.testing.assert_array_equal(roll.returns, returns)
        np.testing.assert_allclose(roll.xy, xy, rtol=0, atol=1e-8)
        np.testing.assert_allclose(roll.heading, heading, rtol=0, atol=1e-8)
        final = np.empty_like(ic[0])
        np.testing.assert_array_equal(world.returns(genomes, ic, final), returns)
        np.testing.assert_array_equal(final, roll.xy[:, -1])

