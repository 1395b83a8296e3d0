"""Plug-in contracts fail loudly or hold by themselves: a selector's learned state is checkpointed without its
author writing state_dict; a series may not take a name a run's files use; an example's cost is declared."""

import json
import sys

import numpy as np
import pytest

from rovermarl.algorithms.base import Algorithm, Series
from rovermarl.algorithms.operators.selectors import KSelector
from rovermarl.algorithms.operators.team import HeterogeneousTeam
from rovermarl.env import make_world
from rovermarl.errors import ConfigError
from rovermarl.record.checkpoint import _decode, _encode
from tests.conftest import ROOT


class RoundRobin(KSelector):
    """k = 1, 2, ..., N, 1, 2, ...: it learns (a counter) and writes no state_dict."""

    def __init__(self, n_agents, f_max=1.0):
        super().__init__(n_agents, f_max)
        self.arms = tuple(range(1, n_agents + 1))
        self.i = 0
        self.seen = np.zeros(n_agents)

    def choose(self, rng):
        return self.arms[self.i % len(self.arms)]

    def update(self, k, f_child, f_parent):
        self.i += 1
        self.seen[k - 1] += f_child


def _checkpointed(state: dict) -> dict:
    """A state through a checkpoint's encoding and JSON, as a resumed run gets it."""
    arrays = {}
    meta = json.loads(json.dumps(_encode(state, arrays)))
    return _decode(meta, arrays)


def test_a_selector_without_state_dict_resumes_where_it_was():
    rng, whole = np.random.default_rng(0), RoundRobin(4)
    want = []
    for t in range(11):
        want.append(whole.choose(rng))
        whole.update(want[-1], float(t), 0.0)
    first, got = RoundRobin(4), []
    for t in range(6):                                                  # a chunk of 6 generations
        got.append(first.choose(rng))
        first.update(got[-1], float(t), 0.0)
    resumed = RoundRobin(4)
    resumed.load_state_dict(_checkpointed(first.state_dict()))
    for t in range(6, 11):
        got.append(resumed.choose(rng))
        resumed.update(got[-1], float(t), 0.0)
    assert got == want == [1, 2, 3, 4, 1, 2, 3, 4, 1, 2, 3]            # not 1, 2, 3, 4, 1, 2, 1, 2, ...
    np.testing.assert_array_equal(resumed.seen, whole.seen)
    assert resumed.seen.dtype == np.float64 and isinstance(resumed.arms, tuple)


@pytest.mark.parametrize("name", ["score", "genomes", "seed", "heldout_score", "behaviour_xy"])
def test_a_series_under_a_reserved_name_is_refused_in_one_line(name):
    class Clash(Algorithm):
        series = (Series(name, "float64"),)

    with pytest.raises(ConfigError) as e:
        Clash(make_world("solo")).check_series()
    assert "\n" not in str(e.value) and name in str(e.value) and "Clash" in str(e.value)


def test_random_search_declares_lam_evaluations_per_generation():
    sys.path.insert(0, str(ROOT / "examples" / "random_search"))
    try:
        from random_search import RandomSearch
    finally:
        sys.path.pop(0)
    assert RandomSearch(make_world("solo"), lam=4).evaluations_per_generation() == 4.0


def test_random_search_spends_exactly_lam_evaluations_and_the_observer_sees_each_accepted_team():
    """The evaluation returns the team's final positions with its score, so an algorithm that keeps a child other
    than the last evaluated needs no re-evaluation: the observer's occupancy is the accepted team's own."""
    from omegaconf import OmegaConf

    from rovermarl.runner.chunk import Run
    sys.path.insert(0, str(ROOT))

    from rovermarl.config import compose_config
    cfg = compose_config("generations=40", "parallel=serial", "setup=duo")
    algo = OmegaConf.load(ROOT / "examples/random_search/algorithm/random_search.yaml")
    algo["_target_"] = "examples.random_search.random_search.RandomSearch"
    cfg.algorithm = algo
    run = Run(cfg, 3)
    calls = run.evaluate.calls
    run.advance(40)
    assert run.evaluate.calls - calls == 40 * 4                       # lam = 4 per generation, no re-evaluation
    team = run.team
    xy = np.empty((16, 4, 2))
    run.evaluate.world.evaluate(team, run.ic, xy)
    np.testing.assert_array_equal(run.observer.parent_xy, xy)         # the accepted team's own final positions


def test_the_observer_refuses_a_team_without_its_final_positions_in_one_line():
    from rovermarl.algorithms.base import AlgorithmError
    from rovermarl.record.events import BehaviourObserver
    world = make_world("solo")
    obs = BehaviourObserver(world, world.run_ic(0), {})
    team = np.zeros((4, world.n_params))
    with pytest.raises(AlgorithmError, match=r"pass on the final_xy of evaluate.measure\(genomes\)") as e:
        obs.accepted(1, team, 2.0, True, None)
    assert "\n" not in str(e.value)
    with pytest.raises(AlgorithmError):
        obs.evaluated(np.array([True, False, False, False]), None)


class Undeclared(Algorithm):
    """Returns its state as a plain dict: no declared RunState type."""

    def _init(self, streams, evaluate):
        return {"score": 0.0}, 0.0


def test_a_state_not_of_the_declared_type_is_refused_in_one_line():
    from rovermarl.algorithms.base import AlgorithmError
    from rovermarl.env.streams import RunStreams

    with pytest.raises(AlgorithmError) as e:
        Undeclared(make_world("solo")).init(RunStreams(0), None)
    assert "\n" not in str(e.value) and "Undeclared._init gave a dict" in str(e.value) and "RunState" in str(e.value)


def test_a_state_of_other_fields_is_refused_naming_them():
    from rovermarl.algorithms.cc11es import CC11ESState

    good = {"score": 1.0, "parents": np.zeros((4, 3)), "rng_mut": {}, "rng_sel": {}, "selector": {}}
    assert CC11ESState.from_dict(good).as_dict().keys() == good.keys()
    with pytest.raises(ValueError, match=r"has no field extra; lacks selector$"):
        CC11ESState.from_dict({**{k: v for k, v in good.items() if k != "selector"}, "extra": 1})


@pytest.mark.parametrize("name", ["evaluate_lots", "__name__"])
def test_a_kernel_call_the_world_lacks_is_refused_before_work_in_one_line_naming_the_file(monkeypatch, name):
    from rovermarl.algorithms import cma
    from rovermarl.config import compose_config
    from rovermarl.runner.validate import validate

    monkeypatch.setattr(cma.SepCMA, "kernel_calls", (name,))
    with pytest.raises(ConfigError) as e:
        validate(compose_config("setup=solo", "algorithm=cma"))
    assert str(e.value) == (f"algorithm.kernel_calls={name}: SepCMA ({cma.__file__}) names no function of the world "
                            "kernel rovermarl.env.kernel.fused")


class ShortChildren(HeterogeneousTeam):
    """A team plug-in whose mutate drops each child's last parameter."""

    def mutate(self, parents, chosen, mutation, rng):
        return super().mutate(parents, chosen, mutation, rng)[:, :-1]


def test_a_team_whose_children_lose_the_parents_shape_is_refused_in_one_line_naming_its_file():
    from rovermarl.algorithms.base import AlgorithmError
    from rovermarl.config import compose_config
    from rovermarl.runner.chunk import Run
    cfg = compose_config("generations=20", "parallel=serial")
    cfg.team = {"_target_": f"{__name__}.ShortChildren"}
    with pytest.raises(AlgorithmError) as e:
        Run(cfg, 0).advance(5)
    assert f"team {__name__}.ShortChildren ({__file__}): mutate returned (4, 657)" in str(e.value)
    assert "parents' shape (4, 658)" in str(e.value) and "\n" not in str(e.value)
