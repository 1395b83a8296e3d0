"""rovermarl.vector: B environments in one compiled call give World.returns's episode returns for the same policy
and initial conditions (every reading, float32, a world plug-in), auto-reset, seeds per environment, and the
Gymnasium view with the agents flattened."""

import sys

import numpy as np
import pytest

from rovermarl.env import kernel, make_world
from rovermarl.runner import Run
from rovermarl.vector import GymVectorEnv, VectorEnv
from tests.conftest import ROOT, make_cfg


@pytest.fixture(scope="module")
def trained():
    """A team that reaches POIs: 300 generations of CC-(1+1)-ES on duo."""
    run = Run(make_cfg("setup=duo", "generations=300", "record=off"), 0)
    run.advance(300)
    return run.team


def play(env, genomes, ic):
    """One episode of the genome team from ``ic``: the rewards' sum per environment, and the infos of the last step."""
    obs, _ = env.reset(options={"ic": ic})
    total = np.zeros(env.num_envs)
    world = env.world
    for t in range(world.steps):
        act = np.empty((env.num_envs, env.n_agents, 2), world.dtype)
        kernel.act(genomes.astype(world.dtype), obs[..., :world.obs_dim].copy(), world.policy.hidden, act)
        obs, rew, term, trunc, infos = env.step(act)
        assert (rew == rew[:, :1]).all() and not trunc.any() and term.all() == (t == world.steps - 1)
        total += rew[:, 0]
    return total, infos


@pytest.mark.parametrize("overrides", [{}, {"reward": "any_step"}, {"reward": "mean_step", "speed": "clip"},
                                       {"reward": "best_step"}, {"dtype": "float32"}])
def test_episode_returns_are_the_worlds(trained, overrides):
    world = make_world("duo", **overrides)
    ic = world.run_ic(7)
    want = world.returns(trained, ic)
    assert want.max() > 0                                                # a team that scores
    total, infos = play(VectorEnv(16, world=world, time_feature=True), trained, ic)
    np.testing.assert_array_equal(infos["final_return"], want)
    np.testing.assert_allclose(total, want, rtol=0, atol=1e-12)


def test_a_world_plugin_steps_with_its_own_hooks():
    sys.path.insert(0, str(ROOT))
    from examples.random_pois.random_pois import RandomPois
    world = RandomPois(coupling=(1,) * 10, value=(1.0,) * 10)
    genomes = np.random.default_rng(1).uniform(-2, 2, (4, world.n_params))
    ic = world.initial_conditions(seed=4, n=32)
    _, infos = play(VectorEnv(32, world=world), genomes, ic)
    np.testing.assert_array_equal(infos["final_return"], world.returns(genomes, ic))


def test_auto_reset_and_seeds_per_environment():
    env = VectorEnv(8, setup="duo")
    first, _ = env.reset(seed=5)
    again, _ = env.reset(seed=5)
    np.testing.assert_array_equal(first, again)
    np.testing.assert_array_equal(env.xy, env.world.initial_conditions(np.random.SeedSequence(5), n=8).xy)
    for _ in range(env.world.steps):
        obs, rew, term, trunc, infos = env.step(np.zeros((8, 4, 2)))
    assert term.all() and "final_obs" in infos and env.t == 0          # the next episode's first observations
    assert not np.array_equal(obs, infos["final_obs"]) and not np.array_equal(obs, first)
    env.reset(seed=list(range(10, 18)))
    for b in (0, 7):
        own = env.world.initial_conditions(np.random.SeedSequence(10 + b), n=1)
        np.testing.assert_array_equal(env.xy[b], own.xy[0])
    with pytest.raises(ValueError, match="8 environments"):
        env.reset(seed=[1, 2])
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((8, 4)))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full((8, 4, 2), np.nan))


def test_the_gymnasium_view_flattens_the_agents():
    env = GymVectorEnv(num_envs=6, setup="solo")
    obs, _ = env.reset(seed=0)
    assert env.num_envs == 24 and obs.shape == (24, 39) and env.observation_space.contains(obs)
    for _ in range(15):
        obs, rew, term, trunc, infos = env.step(env.action_space.sample())
        assert obs.shape == (24, 39) and rew.shape == term.shape == trunc.shape == (24,)
        assert env.observation_space.contains(obs)
    assert term.all() and infos["return"].shape == (6,)
    obs, rew, term, trunc, infos = env.step(env.action_space.sample())     # next-step auto-reset: a new episode
    assert not term.any() and not rew.any() and infos["step"] == 0 and env.observation_space.contains(obs)


def test_gymnasium_wrappers_accept_the_gymnasium_view():
    """Gymnasium's vector wrappers (which refuse same-step auto-reset) wrap it and run through an episode's end."""
    from gymnasium.wrappers import vector as wrappers

    env = wrappers.RecordEpisodeStatistics(wrappers.FlattenObservation(wrappers.NormalizeObservation(
        GymVectorEnv(num_envs=4, setup="solo"))))
    obs, _ = env.reset(seed=0)
    assert obs.shape == (16, 39)
    ended = 0
    for _ in range(2 * 16):
        obs, rew, term, trunc, infos = env.step(env.action_space.sample())
        assert np.isfinite(obs).all() and obs.shape == (16, 39)
        if "episode" in infos:
            ended += int(infos["_episode"].sum())
            assert np.all(infos["episode"]["l"][infos["_episode"]] == 15)
    assert ended == 2 * 16                                                 # two episodes of 16 sub-environments


def test_starts_are_taken_in_turn():
    """starts=ic: every reset takes the next B of the E given starts, cycling (how PPO trains on fixed starts)."""
    w = make_world("solo")
    ic = w.run_ic(3)                                                       # E = 16
    env = VectorEnv(num_envs=6, world=w, starts=ic, autoreset=False)
    seen = []
    for _ in range(8):                                                     # 48 starts = 3 rounds of 16
        env.reset()
        seen.append(env.heading.copy())
    order = np.concatenate(seen)
    assert np.array_equal(order, np.tile(np.asarray(ic[1], order.dtype), (3, 1)))
    assert env.cursor == 48
