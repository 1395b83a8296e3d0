"""The PettingZoo environment: PettingZoo's own API tests, and a team of genomes driven through it gets exactly
World.evaluate's returns on the same initial conditions, under every world reading."""

import numpy as np
import pytest
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test

from rovermarl.env import make_world
from rovermarl.pettingzoo import env, genome_policy, parallel_env
from rovermarl.runner import Run
from tests.conftest import make_cfg


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_parallel_api_test_passes(dtype):
    parallel_api_test(parallel_env("duo", dtype=dtype), num_cycles=100)


def test_aec_api_test_passes():
    api_test(env("duo"), num_cycles=100)


def test_seeding_is_deterministic():
    parallel_seed_test(lambda: parallel_env("solo"))


def test_max_cycles_test_passes_max_cycles_is_the_horizon():
    import rovermarl.pettingzoo as module
    max_cycles_test(module)
    assert parallel_env(max_cycles=7).world.steps == 7
    with pytest.raises(ValueError, match="both set the horizon"):
        parallel_env(max_cycles=7, steps=9)


def test_render_test_passes_and_human_without_a_display_says_so(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    render_test(lambda render_mode=None: env(render_mode=render_mode))
    e = parallel_env(render_mode="human")
    e.reset(seed=0)
    with pytest.warns(UserWarning, match="no display"):
        assert e.render() is None


def test_state_time_feature_and_the_default_setup():
    e = parallel_env(time_feature=True)
    assert e.world.name == "solo"                                       # the package's default setup
    obs, _ = e.reset(seed=3)
    assert obs["rover_0"].shape == (39,) and obs["rover_0"][-1] == 0.0
    assert e.observation_space("rover_0").contains(obs["rover_0"])
    state = e.state()
    assert e.state_space.contains(state) and state.shape == (4 * 4 + 1,)
    np.testing.assert_array_equal(state[:16].reshape(4, 4)[:, :2], e.xy[0])
    for t in range(1, e.world.steps + 1):
        obs, *_ = e.step({a: np.zeros(2) for a in e.agents})
        assert obs["rover_0"][-1] == np.float64(t / e.world.steps).astype(obs["rover_0"].dtype)
        assert e.state()[16] == t / e.world.steps


@pytest.fixture(scope="module")
def trained():
    """A team of genomes that reaches POIs: 300 generations of CC-(1+1)-ES on duo."""
    run = Run(make_cfg("setup=duo", "generations=300", "record=off"), 0)
    run.advance(300)
    return run.team


def episode(e, policy, seed):
    obs, infos = e.reset(seed=seed)
    rewards = []
    while e.agents:
        obs, rew, term, trunc, infos = e.step(policy(obs))
        rewards.append(rew["rover_0"])
        assert len(set(rew.values())) == 1 and not any(trunc.values())
        assert all(term.values()) == (not e.agents)                    # terminated at the horizon, not before
    return np.array(rewards), infos


@pytest.mark.parametrize("overrides", [{}, {"reward": "any_step"}, {"reward": "best_step"},
                                       {"reward": "mean_step", "speed": "clip", "poi_type": "value"},
                                       {"poi_type": "sign"}, {"dtype": "float32"}])
def test_a_genome_team_gets_exactly_the_worlds_returns(overrides, trained):
    world = make_world("duo", **overrides)
    rng = np.random.default_rng(5)
    got, want = [], []
    for seed in range(12):
        genomes = trained + rng.normal(0, 0.05 * (seed % 3), trained.shape)   # a trained team, and neighbours
        e = parallel_env("duo", **overrides)
        rewards, infos = episode(e, genome_policy(world, genomes), seed)
        ic = world.initial_conditions(seed=seed, n=1)
        want.append(world.returns(genomes, ic)[0])
        got.append(infos["rover_0"]["return"])
        assert np.isclose(rewards.sum(), got[-1], rtol=0, atol=1e-12)
        if world.reward == "final":
            assert (rewards[:-1] == 0).all()
        traj = world.rollout(genomes, ic)                         # the same path, step by step
        assert np.array_equal(e.path, traj.xy[0])
    assert got == want                                           # bit for bit
    assert len(set(want)) > 1 and max(want) > 0                  # the check saw different, non-zero returns


def test_infos_and_actions():
    e = parallel_env("duo", n_rovers=2, steps=3)
    obs, infos = e.reset(seed=1)
    assert e.possible_agents == ["rover_0", "rover_1"] and obs["rover_1"].shape == (3 * 10 + 2 * 2,)
    assert infos["rover_0"]["occupancy"].shape == (10,) and infos["rover_0"]["step"] == 0
    before = e.xy.copy()
    e.step({"rover_0": np.array([5.0, 0.0], np.float32)})        # clipped to 1; rover_1 gets (0, 0)
    moved = np.linalg.norm(e.xy[0] - before[0], axis=1)
    assert np.isclose(moved[0], 1.0) and np.isclose(moved[1], 0.5)
    with pytest.raises(ValueError, match="finite"):
        e.step({"rover_0": [np.nan, 0.0]})


RULE = "an action is 2 finite real numbers (speed, turn), clipped to [-1, 1]"


@pytest.mark.parametrize("action,problem", [
    ([np.inf, 0.0], "is not finite ([inf, 0.])"),
    (np.array([0.5, -np.inf], np.float32), "is not finite ([ 0.5, -inf])"),
    ([np.nan, 0.0], "is not finite ([nan, 0.])"),
    ([1 + 2j, 0.0], "is complex ([1.+2.j, 0.+0.j])"),
    (np.array([0.5, 0.0], np.complex128), "is complex"),
    ([1.0, 0.0, 0.0], "has shape (3,), not (2,)"),
    ([[1.0, 0.0]], "has shape (1, 2), not (2,)"),
    (0.5, "has shape (), not (2,)"),
    ([[1.0], [0.0, 1.0]], "is not an array of numbers"),
    (["a", "b"], "is not real numbers (dtype <U1"),
    (None, "is None"),
])
@pytest.mark.parametrize("agent", ["rover_0", "rover_3"])
def test_a_bad_action_is_refused_naming_the_agent_before_anything_changes(action, problem, agent):
    e = parallel_env("duo")
    e.reset(seed=2)
    before = (e.xy.copy(), e.heading.copy(), e.path.copy(), e.t, e.value, list(e.agents))
    actions = {a: np.zeros(2) for a in e.agents} | {agent: action}
    with pytest.raises(ValueError) as err:
        e.step(actions)
    message = str(err.value)
    assert message.startswith(f"actions[{agent!r}] {problem}") and message.endswith(f": {RULE}")
    assert "\n" not in message
    xy, heading, path, t, value, agents = before
    assert np.array_equal(e.xy, xy) and np.array_equal(e.heading, heading)
    assert np.array_equal(e.path, path, equal_nan=True)          # beyond step t it is np.empty's: NaN may be there
    assert (e.t, e.value, e.agents) == (t, value, agents)
    e.step({a: np.zeros(2) for a in e.agents})                   # the episode goes on from where it was
    assert e.t == 1


@pytest.mark.parametrize("key", ["rover_4", "rover", 0])
def test_an_unknown_agent_in_the_actions_is_refused_before_anything_changes(key):
    e = parallel_env("duo")
    e.reset(seed=2)
    xy = e.xy.copy()
    with pytest.raises(ValueError) as err:
        e.step({"rover_0": [1.0, 0.0], key: [1.0, 0.0]})
    assert str(err.value) == f"actions[{key!r}]: no such agent; the agents are rover_0, rover_1, rover_2, rover_3"
    assert np.array_equal(e.xy, xy) and e.t == 0
    with pytest.raises(ValueError, match="^actions must be a dict of agent -> action, got list$"):
        e.step([[1.0, 0.0]] * 4)


def test_the_aec_env_refuses_a_bad_action_at_that_agents_step():
    e = env("duo")
    e.reset(seed=2)
    e.step(np.array([1.0, 0.0]))                                 # rover_0
    assert e.agent_selection == "rover_1"
    for bad, problem in (([np.inf, 0.0], "is not finite"), ([1j, 0.0], "is complex"), ([1.0], "has shape (1,)")):
        with pytest.raises(ValueError) as err:
            e.step(bad)
        assert str(err.value).startswith(f"actions['rover_1'] {problem}") and str(err.value).endswith(RULE)
        assert e.agent_selection == "rover_1"                    # the turn did not move on
    for _ in range(3):
        e.step(np.array([0.0, 0.0]))                             # rover_1 .. rover_3: the world steps
    assert e.unwrapped.t == 1 and e.agent_selection == "rover_0"


@pytest.mark.parametrize("seed", [-1, 1.5, 2.0, "a", "3", True, False, np.int64(-1), [1, 2]])
def test_reset_refuses_a_bad_seed_in_one_line(seed):
    e = parallel_env("duo")
    with pytest.raises(ValueError) as err:
        e.reset(seed=seed)
    message = str(err.value)
    assert message.startswith("seed=") and message.endswith(": must be None or an integer >= 0")
    assert "\n" not in message and not e.agents


def test_reset_takes_python_and_numpy_integer_seeds():
    a, b = parallel_env("duo"), parallel_env("duo")
    obs_a, _ = a.reset(seed=7)
    obs_b, _ = b.reset(seed=np.int64(7))
    assert all(np.array_equal(obs_a[k], obs_b[k]) for k in obs_a)
    a.reset(seed=0)
    a.reset(seed=2**70)


def test_occupancy_counts_rovers_at_pois():
    e = parallel_env("duo")
    e.reset(seed=0)
    e.xy[0, :2] = e.world.poi_xy[0]
    infos = e._infos()
    assert infos["rover_3"]["occupancy"][0] == 2 and infos["rover_3"]["occupancy"].sum() == 2


def test_render_draws_an_image():
    e = parallel_env("solo", render_mode="rgb_array")
    assert parallel_env("solo").render() is None
    e.reset(seed=0)
    e.step({a: np.array([1.0, 0.0]) for a in e.agents})
    image = e.render()
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 5      # more than a blank canvas
