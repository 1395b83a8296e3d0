"""(1+lambda) random search over the whole team: a complete algorithm plug-in, one class plus one yaml.

Each generation draws ``lam`` child teams, each the parent team with ``N(0, sigma^2)`` added to every parameter
of every rover, evaluates them all (in one ``World.evaluate_many`` call, through the runner's ``evaluate.many``
where there is one) and keeps the best child if it scores at least as well as the parent. A generation therefore
costs ``lam`` team evaluations. Besides the score it records one series of its own,
``best_child`` (the best child's score in each generation).

Run it from the repository root (``python -m`` puts the current directory on the import path)::

    python -m rovermarl.train algorithm=random_search hydra.searchpath=[file://examples/random_search] \
        generations=200 seeds=2
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rovermarl import errors
from rovermarl.algorithms import Algorithm, RunState, Series


@dataclass(kw_only=True)
class SearchState(RunState):
    """The run's state: ``team`` (N, P), its ``score``, and ``rng`` (the bit-generator state of the mutation
    stream)."""

    team: np.ndarray
    rng: dict


class RandomSearch(Algorithm):
    """Built from ``random_search.yaml``; its run state is :class:`SearchState`."""

    state_type = SearchState
    kernel_calls = ("evaluate_many",)         # the world kernel's batch call (measure_many): compiled ahead if cold

    def __init__(self, world, lam: int = 4, sigma: float = 0.1, init_low: float = -2.0, init_high: float = 2.0):
        super().__init__(world)
        self.lam = errors.integer("lam", lam, 1)
        self.sigma = errors.number("sigma", sigma, 0)
        self.low, self.high = errors.number("init_low", init_low), errors.number("init_high", init_high)
        self.series = (Series("best_child", "float64", fill=np.nan, doc="score of the best of the lam children"),)

    def evaluations_per_generation(self, fresh_ic: bool = False) -> float:
        """``lam`` children per generation."""
        return float(self.lam)

    def _init(self, streams, evaluate):
        shape = (self.world.n_rovers, self.world.n_params)
        team = np.random.default_rng(streams.algorithm).uniform(self.low, self.high, shape)
        measured = evaluate.measure(team)                           # the score, and what the observer reads
        return SearchState(team=team, score=measured.score,
                           rng=np.random.default_rng(streams.mutation).bit_generator.state), measured

    def _team(self, state):
        return state.team

    def _advance(self, state, generation, n, evaluate, observer):
        rng = np.random.Generator(np.random.PCG64())
        rng.bit_generator.state = state.rng
        team, score = state.team, float(state.score)
        best_child, after = np.empty(n), np.empty(n)
        for t in range(n):
            children = team + rng.normal(0.0, self.sigma, (self.lam, *team.shape))   # (lam, N, P)
            measured = evaluate.measure_many(children)            # scores and final positions, in one call
            scores = np.array([m.score for m in measured])
            best = int(np.argmax(scores))
            if scores[best] >= score:
                observer.accepted(generation + t + 1, children[best], float(scores[best]), scores[best] != score,
                                  measured[best].final_xy)
                team, score = children[best], float(scores[best])
            best_child[t], after[t] = scores[best], score
        return SearchState(team=team, score=score, rng=rng.bit_generator.state), {"score": after,
                                                                                  "best_child": best_child}
