"""The classic rover-domain CCEA, a baseline (after the AADI lab's code; our own): one population of ``pop_size``
genomes per rover, teams formed by shuffling the populations, each member scored by its team's credit (G, D or D++;
:mod:`~rovermarl.algorithms.credit`). docs/BASELINES.md, "What runs", gives its four steps per generation; they are
marked 1.-4. in :meth:`CCEA._advance`.

``final_team``: ``last`` (default) makes the elites team of the last generation the run's team; ``best`` keeps the
best elites team so far (:func:`~rovermarl.algorithms.final_team.keep_best`). Under ``evaluation.fresh_ic`` (SPEC
section 8) each generation draws its own initial conditions and scores every team there. A generation costs
``pop_size + 1`` team evaluations (``+ 1`` for ``best`` under ``fresh_ic``), counted by the ``team_evals`` series.
Run state: :class:`CCEAState`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rovermarl import errors
from rovermarl.algorithms.base import Algorithm, RunState, Series, build_operator, generator, init_range, python_loop
from rovermarl.algorithms.credit import CREDITS, credit
from rovermarl.algorithms.final_team import FINAL_TEAMS, keep_best


@dataclass(kw_only=True)
class CCEAState(RunState):
    """``pops`` (N, pop_size, P): each rover's population; ``score``: the run's team's F (the elites', or the kept
    team's under ``final_team=best``, whose genomes (N, P) are ``kept``, else None); ``best``: the best F so far (the
    behaviour observer logs new bests); ``evals``: team evaluations so far; ``rng``: the ``mutation`` stream's
    bit-generator state."""

    pops: np.ndarray
    best: float
    evals: int
    rng: dict
    kept: np.ndarray | None = None


class CCEA(Algorithm):
    """Built from ``conf/algorithm/ccea.yaml``: ``pop_size``, ``elites``, ``reward`` (one of
    :data:`~rovermarl.algorithms.credit.CREDITS`), the ``mutation`` node and the initial genome range."""

    def __init__(self, world, mutation, pop_size: int = 10, elites: int = 1, reward: str = "global",
                 init_low: float = -2.0, init_high: float = 2.0, final_team: str = "last", loop: str = "auto"):
        super().__init__(world)
        self.final_team = errors.choice("final_team", final_team, FINAL_TEAMS)
        python_loop(loop, "the CCEA")
        self.pop_size = errors.integer("pop_size", pop_size, 2, 100_000)
        self.elites = errors.integer("elites", elites, 1, self.pop_size - 1)   # slot 0: the best
        self.reward = errors.choice("reward", reward, CREDITS)
        self.low, self.high = init_range(init_low, init_high)
        self.mutate = build_operator(mutation, "mutation")
        self.series = (
            Series("team_evals", "int64", doc="team evaluations so far, the initial team's included"),
            Series("fitness", "float64", (world.n_rovers,), np.nan, "each population's best fitness (its credit)",
                   tuple(f"rover{i}" for i in range(world.n_rovers))),
        )

    fresh_ic = True
    state_type = CCEAState

    def evaluations_per_generation(self, fresh_ic: bool = False) -> float:
        return self.pop_size + 1.0 + (fresh_ic and self.final_team == "best")

    def _init(self, streams, evaluate):
        size = (self.world.n_rovers, self.pop_size, self.world.n_params)
        pops = np.random.default_rng(streams.algorithm).uniform(self.low, self.high, size)
        measured = evaluate.measure(_elites(pops))
        return CCEAState(pops=pops, score=measured.score, best=measured.score, evals=1,
                         rng=np.random.default_rng(streams.mutation).bit_generator.state,
                         kept=_elites(pops) if self.final_team == "best" else None), measured

    def _team(self, state):
        return np.ascontiguousarray(state.kept) if self.final_team == "best" else _elites(state.pops)

    def _advance(self, state, generation, n, evaluate, observer):
        rng = generator(state.rng)
        pops, best, evals = np.array(state.pops, dtype=np.float64), float(state.best), int(state.evals)
        keep = self.final_team == "best"
        kept = np.array(state.kept, dtype=np.float64) if keep else None
        score, h = np.empty(n), {s.name: s.empty(n) for s in self.series}
        f_kept = float(state.score)
        for t in range(n):
            if evaluate.fresh:
                evaluate.draw(generation + t + 1)                                           # SPEC section 8
            teams = np.argsort(rng.random((self.world.n_rovers, self.pop_size)), axis=1)   # 1. shuffle, pair
            fitness = self._fitness(pops, teams, evaluate)                                  # 2. credit
            pops, h["fitness"][t] = self._select(pops, fitness, rng)                        # 3. select, mutate
            team = _elites(pops)
            measured = evaluate.measure(team)                                               # 4. the elites team
            evals += self.pop_size + 1
            if keep:                                                                        # the kept team
                kept, measured = keep_best(evaluate, kept, f_kept, team, measured)
                team, f_kept, evals = kept, measured.score, evals + evaluate.fresh
            f, final_xy = measured
            observer.accepted(generation + t + 1, team, f, f > best, final_xy)
            best = max(best, f)
            score[t], h["team_evals"][t] = f, evals
        return CCEAState(pops=pops, score=score[-1] if n else state.score, best=best, evals=evals,
                         rng=rng.bit_generator.state, kept=kept), {"score": score, **h}

    def _fitness(self, pops, teams, evaluate) -> np.ndarray:
        """Each member's credit (N, pop_size) from the teams (N, pop_size): team j is member ``teams[r, j]`` of
        every population r."""
        rovers = np.arange(self.world.n_rovers)
        fitness = np.empty(teams.shape)
        for j in range(self.pop_size):
            genomes = pops[rovers, teams[:, j]]
            if self.reward == "global":
                fitness[rovers, teams[:, j]] = evaluate.score(genomes)
            else:
                roll = evaluate.rollout(genomes)
                credits = credit(self.reward, self.world, roll.xy, roll.returns, roll.layout)   # (N, E)
                fitness[rovers, teams[:, j]] = credits.mean(axis=1)
        return fitness

    def _select(self, pops, fitness, rng) -> tuple[np.ndarray, np.ndarray]:
        """The next populations (elites first, then mutated winners of binary tournaments, a tie by a coin) and each
        population's best fitness (N,). pops (N, pop_size, P), fitness (N, pop_size)."""
        rovers, size, e = self.world.n_rovers, self.pop_size, self.elites
        order = np.argsort(-fitness, axis=1, kind="stable")                      # best first, ties by index
        a = rng.integers(0, size, (rovers, size - e))
        b = (a + rng.integers(1, size, (rovers, size - e))) % size              # a distinct rival
        fa, fb = np.take_along_axis(fitness, a, 1), np.take_along_axis(fitness, b, 1)
        winner = np.where(fa > fb, a, np.where(fa < fb, b, np.where(rng.random(a.shape) < 0.5, a, b)))
        out = np.empty_like(pops)
        for r in range(rovers):
            out[r, :e] = pops[r, order[r, :e]]
            for s in range(size - e):
                out[r, e + s] = self.mutate(pops[r, winner[r, s]], rng)
        return out, fitness[np.arange(rovers), order[:, 0]]


def _elites(pops: np.ndarray) -> np.ndarray:
    """The team of each population's best: slot 0 of pops (N, pop_size, P) -> genomes (N, P)."""
    return np.ascontiguousarray(pops[:, 0])
