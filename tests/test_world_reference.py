"""The compiled kernel against a direct numpy transcription of SPEC sections 1-5, on random scenes."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from rovermarl import make_world, policy

WORLDS = {"solo": make_world("solo"), "duo": make_world("duo")}


def bearing(target, origin, heading):
    """Direction of target in the frame of a rover at origin with heading, in [-pi, pi)."""
    dx, dy = target - origin
    b = math.remainder(math.atan2(dy, dx) - heading, 2 * math.pi)   # exact reduction to [-pi, pi]
    return -math.pi if b == math.pi else b


def spec_observe(world, xy, heading):
    """xy (N, 2), heading (N,) -> (N, 3P + 2N), written from the SPEC text."""
    rows = []
    for i in range(world.n_rovers):
        row = []
        for j in range(world.n_pois):
            d = math.hypot(*(world.poi_xy[j] - xy[i]))
            b = bearing(world.poi_xy[j], xy[i], heading[i])
            row += [1.0, 0.0, 0.0] if d > 30 else [d / 30, b / math.pi, world.coupling[j] - 1]
        for m in range(world.n_rovers):
            d = math.hypot(*(xy[m] - xy[i]))
            b = bearing(xy[m], xy[i], heading[i])
            row += [0.0, 0.0] if m == i else [1.0, 0.0] if d > 30 else [d / 30, b / math.pi]
        rows.append(row)
    return np.array(rows)


def spec_return(world, xy):
    total = 0.0
    for j in range(world.n_pois):
        n = sum(math.hypot(*(world.poi_xy[j] - xy[i])) <= 2 for i in range(world.n_rovers))
        total += world.value[j] if n >= world.coupling[j] else 0.0
    return total


def spec_rollout(world, genomes, xy, heading):
    xy, heading = xy.copy(), heading.copy()
    for _ in range(world.steps):
        obs = spec_observe(world, xy, heading)
        a = np.stack([policy.forward(genomes[i], obs[i], world.hidden) for i in range(world.n_rovers)])
        heading = heading + a[:, 1] * math.radians(60)
        v = (a[:, 0] + 1) / 2
        xy = xy + v[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    return spec_return(world, xy)


coord = st.floats(-40, 40, allow_nan=False)
angle = st.floats(-50, 50, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(setup=st.sampled_from(["solo", "duo"]), xy=st.lists(st.tuples(coord, coord), min_size=4, max_size=4),
       heading=st.lists(angle, min_size=4, max_size=4))
def test_observe_matches_spec(setup, xy, heading):
    world = WORLDS[setup]
    xy, heading = np.array(xy), np.array(heading)
    got = world.observe(xy, heading)
    want = spec_observe(world, xy, heading)
    angles = np.zeros(got.shape[1], dtype=bool)
    angles[1:30:3] = angles[31::2] = True                  # bearing / pi columns
    np.testing.assert_allclose(got[:, ~angles], want[:, ~angles], rtol=1e-12, atol=1e-12)
    on_circle = (got[:, angles] - want[:, angles] + 1) % 2 - 1   # -pi and pi - ulp are neighbours
    np.testing.assert_allclose(on_circle, 0, atol=1e-12)
    assert np.all((got[:, angles] >= -1) & (got[:, angles] < 1))


@settings(max_examples=150, deadline=None)
@given(setup=st.sampled_from(["solo", "duo"]), seed=st.integers(0, 2**32 - 1),
       spread=st.floats(0, 3))
def test_team_return_matches_spec(setup, seed, spread):
    world = WORLDS[setup]
    rng = np.random.default_rng(seed)
    xy = world.poi_xy[rng.integers(0, world.n_pois, 4)] + rng.normal(0, spread, (4, 2))
    got = world.team_return(xy)
    assert got == spec_return(world, xy)
    assert 0 <= got <= world.max_return


def test_rollout_returns_match_spec_on_random_teams():
    for setup, world in WORLDS.items():
        rng = np.random.default_rng(len(setup))
        xy, heading = world.initial_conditions(seed=1, n=6)
        for _ in range(4):
            genomes = rng.uniform(-2, 2, (4, world.n_params))
            got = world.returns(genomes, (xy, heading))
            want = [spec_rollout(world, genomes, xy[e], heading[e]) for e in range(6)]
            np.testing.assert_array_equal(got, want)
