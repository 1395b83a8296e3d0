"""Hand-built scenes hold the world to SPEC sections 1-5."""

import math

import numpy as np
import pytest

from rovermarl import make_world
from rovermarl.errors import ConfigError


@pytest.fixture(scope="module")
def solo():
    return make_world("solo")


@pytest.fixture(scope="module")
def duo():
    return make_world("duo")


def poi(world, j, r=0.0, phi=0.0):
    """A point at distance r, direction phi from POI j."""
    return world.poi_xy[j] + r * np.array([math.cos(phi), math.sin(phi)])


def test_sizes_and_geometry(solo, duo):
    assert solo.n_params == 658 and solo.obs_dim == 38 and solo.n_pois == 10
    np.testing.assert_allclose(solo.poi_xy[0], [13, 0], atol=1e-12)
    np.testing.assert_allclose(solo.poi_xy[5], [-13, 0], atol=1e-12)
    np.testing.assert_allclose(solo.poi_xy[2], [13 * math.cos(0.4 * math.pi), 13 * math.sin(0.4 * math.pi)])
    assert duo.coupling == (2, 1, 1, 1, 1, 2, 1, 1, 1, 1)
    assert duo.value == (3, 1, 1, 1, 1, 3, 1, 1, 1, 1)
    assert solo.max_return == 4 and duo.max_return == 6


def test_observation_values(solo):
    xy = np.array([[0.0, 0.0], [3.0, 4.0], [100.0, 0.0], [0.0, -6.0]])
    heading = np.array([0.0, 1.0, 2.0, 3.0])
    obs = solo.observe(xy, heading)
    assert obs.shape == (4, 38)
    o = obs[0]
    for j in range(10):                             # every POI at distance 13, bearing = its angle
        expected = (2 * math.pi * j / 10 + math.pi) % (2 * math.pi) - math.pi
        assert o[3 * j] == pytest.approx(13 / 30)
        assert o[3 * j + 1] == pytest.approx(expected / math.pi)
        assert o[3 * j + 2] == 0.0
    assert o[3 * 5 + 1] == pytest.approx(-1.0)      # bearing pi wraps to -pi: [-pi, pi)
    assert o[3 * 6 + 1] == pytest.approx(-0.8)
    rovers = o[30:].reshape(4, 2)
    np.testing.assert_allclose(rovers[0], [0, 0])   # own slot
    np.testing.assert_allclose(rovers[1], [5 / 30, math.atan2(4, 3) / math.pi])
    np.testing.assert_allclose(rovers[2], [1, 0])   # beyond sensor range
    np.testing.assert_allclose(rovers[3], [6 / 30, -0.5])
    # rover 1 (heading 1 rad) sees rover 0 behind-left: atan2(-4, -3) - 1 wrapped
    b = (math.atan2(-4, -3) - 1.0 + math.pi) % (2 * math.pi) - math.pi
    np.testing.assert_allclose(obs[1, 30:32], [5 / 30, b / math.pi], atol=1e-12)


def test_bearing_wraps_for_any_heading(solo):
    xy = np.zeros((4, 2))
    xy[1:] = 50.0                                   # others out of range
    for turns in (-7, 0, 3, 11):
        heading = np.array([1.5 * math.pi + 2 * math.pi * turns, 0, 0, 0])
        obs = solo.observe(xy, heading)
        assert obs[0, 1] == pytest.approx(0.5)      # POI 0 at angle 0 is +pi/2 in the rover frame
    heading = np.array([math.pi - 0.1, 0, 0, 0])
    xy[0] = poi(solo, 5, 7.0)                       # rover at (-6, 0)
    obs = solo.observe(xy, heading)
    # POI 5 at (-13, 0): direction pi; bearing pi - (pi - 0.1) = 0.1
    assert obs[0, 3 * 5 + 1] == pytest.approx(0.1 / math.pi)
    # POI 0 at (13, 0): direction 0; 0 - (pi - 0.1) = -pi + 0.1
    assert obs[0, 1] == pytest.approx((-math.pi + 0.1) / math.pi)


def test_out_of_range_poi_reads_1_0_0(duo):
    xy = np.array([[-20.0, 0.0], [0, 0], [0, 0], [0, 0]])
    obs = duo.observe(xy, np.zeros(4))
    np.testing.assert_allclose(obs[0, 0:3], [1, 0, 0], atol=1e-12)                  # POI 0 is 33 away
    np.testing.assert_allclose(obs[0, 15:18], [7 / 30, 0, 1], atol=1e-12)           # duo POI 5 is 7 away, type 1
    np.testing.assert_allclose(obs[1, 0:3], [13 / 30, 0, 1], atol=1e-12)
    assert obs[1, 3 * 1 + 2] == 0.0                                     # solo POI type reads 0


def test_observe_batches(solo):
    xy, heading, _ = solo.initial_conditions(seed=3, n=5)
    batch = solo.observe(xy, heading)
    assert batch.shape == (5, 4, 38)
    for e in range(5):
        np.testing.assert_array_equal(batch[e], solo.observe(xy[e], heading[e]))


def test_returns_solo(solo):
    spread = np.stack([poi(solo, j, 1.0, 0.3 * j) for j in (0, 3, 5, 8)])
    assert solo.team_return(spread) == 4
    doubled = spread.copy()
    doubled[1] = poi(solo, 0, 1.5)
    assert solo.team_return(doubled) == 3
    edge = spread.copy()
    edge[0] = [15.0, 0.0]                           # exactly 2 from POI 0: observed (<= 2)
    assert solo.team_return(edge) == 4
    edge[0] = [15.0 + 1e-9, 0.0]
    assert solo.team_return(edge) == 3
    assert solo.team_return(np.zeros((4, 2))) == 0
    batch = np.stack([spread, doubled, np.zeros((4, 2))])
    np.testing.assert_array_equal(solo.team_return(batch), [4, 3, 0])


def test_returns_duo_needs_two_rovers(duo):
    one = np.stack([poi(duo, 0), [0, 0], [0, 0], [0, 0]])
    assert duo.team_return(one) == 0                # a duo POI with one rover gives nothing
    pair = np.stack([poi(duo, 0, 0.5), poi(duo, 0, 1.0, 2.0), poi(duo, 1), poi(duo, 2)])
    assert duo.team_return(pair) == 5
    best = np.stack([poi(duo, 0), poi(duo, 0, 1.9), poi(duo, 5), poi(duo, 5, 0.2, 1.0)])
    assert duo.team_return(best) == 6
    three = np.stack([poi(duo, 0), poi(duo, 0, 1.0), poi(duo, 0, 1.0, 3.0), poi(duo, 7)])
    assert duo.team_return(three) == 4              # 3 rovers on a duo POI still give 3


def constant_action_genome(world, a0, a1):
    """A genome whose policy outputs (a0, a1) whatever it sees: all weights 0, b2 = atanh(a)."""
    g = np.zeros(world.n_params)
    g[-2:] = [20.0 * np.sign(a) if abs(a) == 1 else np.arctanh(a) for a in (a0, a1)]  # tanh(20) == 1.0
    return g


def test_one_kinematic_step_turns_then_moves():
    world = make_world("solo", steps=1)
    genomes = np.stack([constant_action_genome(world, a0, a1)
                        for a0, a1 in ((0.0, 0.5), (1.0, -1.0), (-1.0, 1.0), (0.5, 0.0))])
    xy0 = np.array([[[0.1, 0.2], [-0.3, 0.1], [-0.2, -0.2], [0.4, -0.1]]])
    h0 = np.array([[0.2, 2.0, 3.5, 5.0]])
    roll = world.rollout(genomes, (xy0, h0))
    assert roll.xy.shape == (1, 2, 4, 2) and roll.heading.shape == (1, 2, 4)
    speed = np.array([0.5, 1.0, 0.0, 0.75])
    turn = np.radians(60) * np.array([0.5, -1.0, 1.0, 0.0])
    h1 = h0[0] + turn
    np.testing.assert_allclose(roll.heading[0, 1], h1, atol=1e-12)
    np.testing.assert_allclose(roll.xy[0, 1], xy0[0] + speed[:, None] * np.stack([np.cos(h1), np.sin(h1)], 1),
                               atol=1e-12)
    np.testing.assert_array_equal(roll.xy[0, 0], xy0[0])


def test_rollout_matches_evaluate_and_is_deterministic(duo):
    ic = duo.initial_conditions(seed=0)
    genomes = np.random.default_rng(1).uniform(-2, 2, (4, duo.n_params))
    roll = duo.rollout(genomes, ic)
    assert roll.xy.shape == (16, 16, 4, 2) and roll.heading.shape == (16, 16, 4) and roll.returns.shape == (16,)
    np.testing.assert_array_equal(roll.returns, duo.team_return(roll.xy[:, -1]))
    assert duo.evaluate(genomes, ic) == roll.returns.mean() == duo.evaluate(genomes, ic)
    np.testing.assert_array_equal(roll.xy[:, 0], ic[0])


def test_initial_conditions_boxes_and_headings(solo):
    xy, heading, _ = solo.initial_conditions(seed=7, n=2000)
    assert xy.shape == (2000, 4, 2) and heading.shape == (2000, 4)
    signs = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]])
    scaled = xy * signs
    assert scaled.min() >= 0 and scaled.max() <= 0.5 and scaled.max() > 0.49
    for i in range(4):
        assert heading[:, i].min() >= i * math.pi / 2 and heading[:, i].max() <= (i + 1) * math.pi / 2
    a, b, _ = solo.initial_conditions(seed=7, n=2000)
    np.testing.assert_array_equal(a, xy)
    assert not np.array_equal(solo.initial_conditions(seed=8)[0], xy[:16])


def test_world_rejects_bad_values():
    with pytest.raises(ConfigError, match=r"setup.coupling\[0\]=5"):
        make_world("solo", coupling=[5] + [1] * 9)
    with pytest.raises(ConfigError, match="env.obs_radius"):
        make_world("solo", obs_radius=0)
    with pytest.raises(ConfigError, match="setup=quartet"):
        make_world("quartet")
    with pytest.raises(ValueError, match="genomes must have shape"):
        make_world("solo").evaluate(np.zeros((3, 658)), make_world("solo").initial_conditions())


@pytest.mark.parametrize("n", [3, 6, 8])
def test_start_squares_generalise_the_quadrants(n):
    """For N != 4, rover i starts in the quadrant square turned so its diagonal bisects heading sector i."""
    w = make_world("solo", n_rovers=n)
    xy, heading, _ = w.initial_conditions(0, n=4000)
    phi = w.starts.start_rotation
    c, s = np.cos(-phi), np.sin(-phi)
    back = np.stack([xy[..., 0] * c - xy[..., 1] * s, xy[..., 0] * s + xy[..., 1] * c], axis=-1)
    assert back.min() > -1e-12 and back.max() < 0.5 + 1e-12
    assert np.all(np.abs(back.mean(axis=0) - 0.25) < 0.02)                   # uniform over the square
    sector = 2 * np.pi / n
    assert np.all((heading >= sector * np.arange(n)) & (heading <= sector * (np.arange(n) + 1)))
    bisector = np.arctan2(xy[..., 1].mean(axis=0), xy[..., 0].mean(axis=0)) % (2 * np.pi)
    np.testing.assert_allclose(bisector, (np.arange(n) + 0.5) * sector, atol=0.05)
    assert w.starts.start_squares.shape == (n, 5, 2)


def test_four_rover_start_squares_are_the_quadrants():
    w = make_world("solo")
    np.testing.assert_allclose(w.starts.start_squares[:, 2], [[0.5, 0.5], [-0.5, 0.5], [-0.5, -0.5], [0.5, -0.5]])
    np.testing.assert_allclose(w.starts.start_rotation, np.arange(4) * np.pi / 2)


def test_non_finite_targets_read_as_out_of_range(solo):
    """One sensor encoding for World.observe and the rollout: a target at a NaN or infinite distance reads [1, 0, 0]."""
    xy = np.zeros((4, 2))
    xy[1], xy[2] = [np.nan, 0.0], [np.inf, 0.0]
    obs = solo.observe(xy, np.zeros(4))
    np.testing.assert_array_equal(obs[1, :3], [1, 0, 0])          # a rover at NaN sees no POI
    np.testing.assert_array_equal(obs[0, 32:36], [1, 0, 1, 0])    # rovers 1 and 2 seen from rover 0


def test_max_return_is_a_bound_also_where_observation_discs_overlap():
    # at poi_distance 9 neighbouring POIs are 5.56 apart: a rover within 3 (or 4) of both earns both, so the
    # one-POI-per-rover knapsack (6 on duo) is no bound; the geometry study saw returns up to 8.875 there
    for r in (3.0, 4.0):
        w = make_world("duo", obs_radius=r, poi_distance=9.0)
        assert w.max_return == sum(w.value) == 14.0
        mid = (w.poi_xy[1] + w.poi_xy[2]) / 2                             # between two solo POIs
        xy = np.array([mid, w.poi_xy[3], w.poi_xy[4], w.poi_xy[6]])
        assert w.team_return(xy) > 4.0                                    # 4 rovers, 5 POIs paid
    assert make_world("duo", obs_radius=4.0).max_return == 6.0              # 8.03 apart at 13: no overlap
    assert make_world("duo", obs_radius=2.0, poi_distance=9.0).max_return == 6.0
