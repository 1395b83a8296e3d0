"""The evaluator contract (rovermarl.algorithms.base.Evaluator): an algorithm plug-in written against it alone runs
in the runner, an evaluator written against it alone runs the paper's algorithm, and the observer is told final
positions explicitly (no float carrying data)."""

from dataclasses import dataclass

import numpy as np
import pytest

from rovermarl.algorithms import Algorithm, AlgorithmError, Evaluator, Measured, RunState, RunStreams, Series
from rovermarl.env import Rollout
from rovermarl.runner.chunk import Evaluation, Run, to_plain
from tests.conftest import make_cfg


@dataclass(kw_only=True)
class ContractState(RunState):
    team: np.ndarray
    rng: dict


class ContractSearch(Algorithm):
    """A plug-in that uses every part of the contract: the named streams, measure (score and positions) for the
    team it keeps, score for a probe, rollout for trajectories, and the observer's explicit positions."""

    state_type = ContractState

    def __init__(self, world):
        super().__init__(world)
        self.series = (Series("probe", "float64", fill=np.nan, doc="a mutant's score"),
                       Series("switched", "int16", fill=-1, doc="observer's count"))

    def _init(self, streams: RunStreams, evaluate: Evaluator):
        team = np.random.default_rng(streams.algorithm).uniform(-2, 2, (self.world.n_rovers, self.world.n_params))
        measured = evaluate.measure(team)
        return ContractState(team=team, score=measured.score,
                             rng=np.random.default_rng(streams.mutation).bit_generator.state), measured

    def _team(self, state):
        return state.team

    def _advance(self, state, generation, n, evaluate: Evaluator, observer):
        rng = np.random.default_rng()
        rng.bit_generator.state = state.rng
        team, f = state.team, float(state.score)
        out = {"score": np.empty(n), "probe": np.empty(n), "switched": np.empty(n, np.int16)}
        for t in range(n):
            child = team + rng.normal(0, 0.3, team.shape)
            out["probe"][t] = evaluate.score(child + 1.0)
            measured = evaluate.measure(child)
            assert type(measured.score) is float and measured.final_xy.shape == (self.world.episodes, 4, 2)
            roll = evaluate.rollout(child)
            assert isinstance(roll, Rollout) and roll.returns.mean() == measured.score
            np.testing.assert_array_equal(roll.xy[:, -1], measured.final_xy)
            mutated = np.ones(self.world.n_rovers, bool)
            mutated[0] = False
            out["switched"][t] = observer.evaluated(mutated, measured.final_xy)
            if measured.score >= f:
                observer.accepted(generation + t + 1, child, measured.score, measured.score != f, measured.final_xy)
                team, f = child, measured.score
            out["score"][t] = f
        return ContractState(team=team, score=f, rng=rng.bit_generator.state), out


def test_a_plugin_written_against_the_contract_runs():
    cfg = make_cfg("generations=12", "setup=duo")
    cfg.algorithm = {"_target_": f"{__name__}.ContractSearch"}
    run = Run(to_plain(cfg), 3)
    arrays = run.advance(12)
    assert arrays["score"].shape == (12,) and (np.diff(arrays["score"]) >= 0).all()
    assert (arrays["switched"] >= 0).all()                        # the observer read the positions it was told
    assert run.evaluate.calls == 1 + 3 * 12
    events = run.observer.drain()
    assert events["occupancy"]["generation"][0] == 0              # the initial team's positions, from init


class ScoresOnly(Evaluator):
    """An evaluator written against the contract alone: scores with positions and trajectories, no compiled inputs."""

    def __init__(self, world, ic, keep_final=True, fresh_seed=None):
        self.world, self.ic, self.calls = world, ic, 0

    def measure(self, genomes) -> Measured:
        self.calls += 1
        final = np.empty(self.ic[0].shape)
        return Measured(self.world.evaluate(genomes, self.ic, final), final)

    def rollout(self, genomes) -> Rollout:
        self.calls += 1
        return self.world.rollout(genomes, self.ic)


@pytest.mark.parametrize("overrides", [["k=adaptive"], ["algorithm=ccea", "algorithm.reward=dpp"]])
def test_an_evaluator_written_against_the_contract_runs_the_packaged_algorithms(overrides):
    cfg = to_plain(make_cfg(*overrides, "generations=30", "setup=duo"))
    mine, theirs = Run(cfg, 2, evaluation=ScoresOnly), Run(cfg, 2, evaluation=Evaluation)
    a, b = mine.advance(30), theirs.advance(30)
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert mine.evaluate.calls == theirs.evaluate.calls
    with pytest.raises(AlgorithmError, match="draws no fresh initial conditions"):
        mine.evaluate.draw(1)


def test_the_observer_refuses_a_team_without_positions_in_one_line():
    run = Run(to_plain(make_cfg("generations=5")), 0)
    with pytest.raises(AlgorithmError, match=r"^the behaviour observer was told of a team without its final"):
        run.observer.accepted(1, run.team, 1.0, True, None)


def test_shards_give_the_local_evaluators_trajectories(ray_session):
    """IC shards implement the whole contract: a credit-based learner (rollout) runs on them, bit for bit."""
    from rovermarl.parallel.ray_backend import release_pool
    from rovermarl.parallel.shards import ShardActor, ShardedEvaluation
    release_pool()                  # an earlier test's chunk workers hold both CPUs; the product releases them too
    cfg = to_plain(make_cfg("setup=duo", "generations=3"))
    local = Run(cfg, 4).evaluate
    actors = [ShardActor.remote(cfg) for _ in range(2)]
    try:
        sharded = ShardedEvaluation(actors, local.world, local.ic)
        team = np.random.default_rng(0).uniform(-2, 2, (4, local.world.n_params))
        for got, want in zip(sharded.rollout(team), local.rollout(team), strict=True):
            np.testing.assert_array_equal(got, want)
        assert sharded.measure(team).score == local.measure(team).score and sharded.kernel_inputs() is None
    finally:
        for a in actors:
            ray_session.kill(a)
