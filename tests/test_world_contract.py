"""What a world plug-in declares once: its observation blocks (the policy reads every declared row, and ``sense``
is checked against them when the World is built) and its per-episode state (one per call and per environment).
examples/moving_pois, a world with memory, agrees with a numpy re-simulation on every return."""

import dataclasses
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from rovermarl import errors
from rovermarl.env import make_world
from rovermarl.env.kernel import fused
from rovermarl.vector import VectorEnv
from tests import reference
from tests.conftest import ROOT

sys.path.insert(0, str(ROOT)) if str(ROOT) not in sys.path else None
from examples.moving_pois.moving_pois import MovingPois  # noqa: E402
from examples.obstacles.obstacles import Obstacles  # noqa: E402

SETUP = {"coupling": (1,) * 10, "value": (1.0,) * 10}


def test_a_plugins_extra_sensor_rows_change_the_policys_actions():
    world = Obstacles(**SETUP)
    assert world.obs_dim == 46 and all(np.isin(np.arange(38, 46), r).all() for r in world.kernel.rows)   # read
    team = np.random.default_rng(1).uniform(-2, 2, (4, world.n_params))
    other = team.copy()
    h = world.policy.hidden
    other[:, 38 * h:46 * h] += 3.0                                          # W1's rows of the obstacle block
    ic = world.initial_conditions(seed=2, n=4)
    assert not np.allclose(world.rollout(team, ic).xy, world.rollout(other, ic).xy)


class Unfilled(Obstacles):
    def obs_blocks(self):
        return [*super().obs_blocks(), ("ghost", -np.ones(3), np.ones(3))]


class Undeclared(Obstacles):
    def obs_blocks(self):
        return super().obs_blocks()[:2]


@pytest.mark.parametrize("cls, wrote", [(Unfilled, 46), (Undeclared, 46)])
def test_sense_is_checked_against_the_declared_blocks_in_one_line(cls, wrote):
    said = (rf"{cls.__name__}'s hook sense \(.*obstacles.py\) fills {wrote} observation rows, but its obs_blocks "
            r"\(.*test_world_contract.py\) declares")                          # each file named
    with pytest.raises(errors.ConfigError, match=said) as err:
        cls(**SETUP)
    assert "\n" not in str(err.value)


def _moving():
    return MovingPois(**SETUP)


def test_the_paper_world_keeps_no_state_and_its_own_kernel():
    w = make_world("solo")
    assert w.state == () and w.kernel.state_dims.shape == (0,) and w.compiled is fused


def test_moving_pois_matches_a_numpy_resimulation_on_every_return():
    world = _moving()
    team = np.random.default_rng(3).uniform(-1, 1, (4, world.n_params))
    ic = world.initial_conditions(seed=5, n=12)
    paths = np.stack([world.poi_path(lay) for lay in ic.layout])             # (E, T+1, P, 2)

    def at(e, t):                                                            # the world as SPEC reads it, POIs moved
        return SimpleNamespace(**_fields(world), poi_xy=paths[e, t])

    roll = world.rollout(team, ic)
    xy, heading = ic.xy.copy(), ic.heading.copy()
    for t in range(world.steps):                                             # sense, act, move in numpy
        obs = np.concatenate([reference.observe(at(e, t), xy[e:e + 1], heading[e:e + 1]) for e in range(12)])
        xy, heading = reference.move(world, xy, heading, reference.act(world, team, obs))
        np.testing.assert_allclose(xy, roll.xy[:, t + 1], atol=1e-6)
    want = [reference.team_return(at(e, -1), roll.xy[e:e + 1, -1])[0] for e in range(12)]
    np.testing.assert_array_equal(roll.returns, want)
    on = np.repeat(roll.xy[:, :1], world.steps + 1, axis=1)                  # every rover on a POI's last place
    on[:, -1] = paths[:, -1, :world.n_rovers]
    want = [reference.team_return(at(e, -1), on[e:e + 1, -1])[0] for e in range(12)]
    got = world.episode_return(on, ic.layout)
    np.testing.assert_array_equal(got, want)
    assert (got >= world.n_rovers).all()                                     # the reward follows the POIs
    on[:, -1] = world.poi_xy[:world.n_rovers]                                # where they would be if they stood
    assert (world.episode_return(on, ic.layout) == 0).all()


def _fields(world):
    return {f.name: getattr(world, f.name) for f in dataclasses.fields(world.params) if f.name != "poi_xy"} | {
        "obs_dim": world.obs_dim, "w_max": world.w_max}


def test_two_envs_on_one_world_keep_their_own_state():
    world = _moving()
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (world.steps, 3, world.n_rovers, 2))

    def run(envs, order):
        obs = {i: [envs[i].reset(seed=10 + i)[0]] for i in order}
        for t in range(world.steps):
            for i in order:
                obs[i].append(envs[i].step(acts[t])[0])
        return {i: np.array(o) for i, o in obs.items()}

    alone = {i: run({i: VectorEnv(3, world=world, autoreset=False)}, [i])[i] for i in (0, 1)}
    both = run({i: VectorEnv(3, world=world, autoreset=False) for i in (0, 1)}, [0, 1])
    for i in (0, 1):
        np.testing.assert_array_equal(both[i], alone[i])
    assert not np.array_equal(alone[0], alone[1])


def test_make_world_builds_a_plugin_from_python_and_names_a_bad_key_in_one_line():
    w = make_world("duo", world=MovingPois, drift_radius=3.0, steps=12)
    assert type(w) is MovingPois and w.drift_radius == 3.0 and w.steps == 12 and w.n_pois == 10
    assert type(make_world("solo", world="examples.moving_pois.moving_pois.MovingPois")) is MovingPois
    with pytest.raises(errors.ConfigError, match=r"^env.energy=12.0: unknown key; allowed: .*drift_radius") as e:
        make_world("duo", world=MovingPois, energy=12.0)
    assert "\n" not in str(e.value)
    with pytest.raises(errors.ConfigError, match=r"^world=.*: must be a subclass of rovermarl.env.World"):
        make_world("duo", world=dict)
    with pytest.raises(errors.ConfigError, match=r"^env.drift_radius=-1: must be"):
        make_world("duo", world=MovingPois, drift_radius=-1)
