"""The map of random streams (rovermarl.env.streams): each named stream is the SeedSequence it was when the results
were published (the spawn keys of 4c4ae3c's runner and algorithms), so a new stream cannot shift the others."""

import numpy as np
import pytest

from rovermarl.env import make_world
from rovermarl.env.streams import RunStreams, env_seed, env_stream

# name -> spawn key in SeedSequence(seed): the published map (docs/ARCHITECTURE.md shows it)
PUBLISHED = {"initial conditions": (0,), "algorithm": (1,), "mutation": (2,), "selector": (3,), "held-out": (2**31,)}


def _named(s: RunStreams) -> dict:
    return {"initial conditions": s.initial_conditions(), "algorithm": s.algorithm, "mutation": s.mutation,
            "selector": s.selector, "held-out": s.heldout}


@pytest.mark.parametrize("seed", [0, 7, 2**40])
def test_each_named_stream_has_its_published_spawn_key(seed):
    named = _named(RunStreams(seed))
    assert {k: v.spawn_key for k, v in named.items()} == PUBLISHED
    assert all(v.entropy == seed for v in named.values())
    assert RunStreams(seed).initial_conditions(5).spawn_key == (0, 5)       # evaluation.fresh_ic, generation 5
    assert len({v.spawn_key for v in named.values()}) == len(named)


@pytest.mark.parametrize("seed", [0, 3])
def test_the_streams_draw_what_the_published_spawns_drew(seed):
    """4c4ae3c's runner spawned one child (the initial conditions) and handed the rest to the algorithm, which
    spawned 3 (CC-(1+1)-ES: init, mutation, selector) or 2 (the CCEA: init, its run); the held-out key was 2**31."""
    def state(s):
        return s.generate_state(8).tolist()
    named = _named(RunStreams(seed))
    root = np.random.SeedSequence(seed)
    (ic,) = root.spawn(1)
    init, mut, sel = root.spawn(3)
    assert [state(s) for s in (ic, init, mut, sel)] == \
        [state(named[k]) for k in ("initial conditions", "algorithm", "mutation", "selector")]
    ccea = np.random.SeedSequence(seed)
    ccea.spawn(1)
    assert [state(s) for s in ccea.spawn(2)] == [state(named["algorithm"]), state(named["mutation"])]
    assert state(np.random.SeedSequence(seed, spawn_key=(2**31,))) == state(named["held-out"])
    world = make_world("solo")
    np.testing.assert_array_equal(world.run_ic(seed).xy, world.initial_conditions(ic).xy)


def test_an_environment_draws_from_its_seeds_root():
    a, b = env_stream(5), np.random.default_rng(5)
    np.testing.assert_array_equal(a.random(8), b.random(8))
    assert env_seed(np.int64(3)) == 3
    for bad in (-1, 1.5, True, "3"):
        with pytest.raises(ValueError, match=r"^seed=.*: must be None or an integer >= 0$"):
            env_seed(bad)
