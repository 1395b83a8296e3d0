"""sep-CMA-ES (Ros & Hansen 2008: diagonal covariance) over the whole team, a baseline: one search distribution over
all N x P parameters (4 x 658 = 2632), each generation's ``lam`` samples scored in one
:meth:`Evaluator.measure_many` call; the team is the best sample so far (elitist). Run state: :class:`SepCMAState`.

Diagonal because full CMA-ES's n x n covariance is 55 MB of checkpointed state at n = 2632 and its
eigendecomposition costs more than a generation's 27 team evaluations (docs/LEARNERS.md); sep-CMA's state and
update are O(n), and it adapts in O(n) generations where full CMA needs O(n^2) (a 20,000-evaluation budget is ~740
generations here). The update (Hansen's
tutorial's equations with the separable learning rates, (n + 2) / 3 times larger) is written out here because the
``cma`` package's state does not resume bit-identically from a checkpoint of plain arrays.

Under ``evaluation.fresh_ic`` (SPEC section 8) each generation scores the population and the kept best sample again
on its own initial conditions; a sample replaces it when it scores at least as well there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rovermarl import errors
from rovermarl.algorithms.base import Algorithm, RunState, Series, generator, init_range, python_loop


@dataclass(kw_only=True)
class SepCMAState(RunState):
    """The search distribution: ``mean``, ``diag`` (the diagonal covariance), the paths ``ps`` and ``pc`` (all
    (N*P,)), the step size ``sigma``, the generation ``gen``; the best team so far ``best`` (N, P), scored
    ``score``; ``evals``: team evaluations so far; ``rng``: the ``mutation`` stream's bit-generator state."""

    mean: np.ndarray
    diag: np.ndarray
    ps: np.ndarray
    pc: np.ndarray
    sigma: float
    gen: int
    best: np.ndarray
    evals: int
    rng: dict


class SepCMA(Algorithm):
    """Built from ``conf/algorithm/cma.yaml``: ``sigma`` (initial step size), ``popsize`` (null: 4 + 3 ln n) and the
    initial mean's range ``init_low``..``init_high`` (uniform, like the other learners' initial teams)."""

    def __init__(self, world, sigma: float = 0.5, popsize: int | None = None, init_low: float = -2.0,
                 init_high: float = 2.0, loop: str = "auto"):
        super().__init__(world)
        python_loop(loop, "CMA-ES")
        self.sigma0 = errors.number("sigma", sigma, 0, lo_open=True)
        self.low, self.high = init_range(init_low, init_high)
        self.n = n = world.n_rovers * world.n_params
        self.lam = 4 + int(3 * math.log(n)) if popsize is None else errors.integer("popsize", popsize, 4, 100_000)
        mu = self.lam // 2
        w = math.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
        self.weights = w / w.sum()                                                     # (mu,)
        self.mueff = mueff = 1.0 / float((self.weights ** 2).sum())
        self.cs = (mueff + 2) / (n + mueff + 5)
        self.damps = 1 + 2 * max(0.0, math.sqrt((mueff - 1) / (n + 1)) - 1) + self.cs
        self.cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
        c1 = 2 / ((n + 1.3) ** 2 + mueff)
        cmu = min(1 - c1, 2 * (mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
        self.c1 = c1 * (n + 2) / 3                                                     # separable rates
        self.cmu = min(1 - self.c1, cmu * (n + 2) / 3)
        self.chin = math.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n))
        self.series = (
            Series("team_evals", "int64", doc="team evaluations so far, the initial team's included"),
            Series("sigma", "float64", (), np.nan, "the step size after the generation"),
        )

    fresh_ic = True
    state_type = SepCMAState
    kernel_calls = ("evaluate_many",)                     # each generation's population in one call

    def evaluations_per_generation(self, fresh_ic: bool = False) -> float:
        return float(self.lam + fresh_ic)

    def _init(self, streams, evaluate):
        n = self.n
        mean = np.random.default_rng(streams.algorithm).uniform(self.low, self.high, n)
        best = mean.reshape(self.world.n_rovers, self.world.n_params).copy()
        measured = evaluate.measure(best)
        return SepCMAState(mean=mean, diag=np.ones(n), ps=np.zeros(n), pc=np.zeros(n), sigma=self.sigma0, gen=0,
                           best=best, score=measured.score, evals=1,
                           rng=np.random.default_rng(streams.mutation).bit_generator.state), measured

    def _team(self, state):
        return np.ascontiguousarray(state.best)

    def _advance(self, state, generation, n_gen, evaluate, observer):
        rng = generator(state.rng)
        mean, diag = np.array(state.mean, dtype=np.float64), np.array(state.diag, dtype=np.float64)
        ps, pc = np.array(state.ps, dtype=np.float64), np.array(state.pc, dtype=np.float64)
        sigma, gen, evals = float(state.sigma), int(state.gen), int(state.evals)
        best, best_score = np.array(state.best, dtype=np.float64), float(state.score)
        score, h = np.empty(n_gen), {s.name: s.empty(n_gen) for s in self.series}
        shape, mu = (self.lam, self.world.n_rovers, self.world.n_params), self.lam // 2
        for t in range(n_gen):
            z = rng.standard_normal((self.lam, self.n))                                # x = m + sigma * sqrt(C) * z
            y = z * np.sqrt(diag)
            x = mean + sigma * y
            if evaluate.fresh:                                                         # new starts: the kept best
                evaluate.draw(generation + t + 1)                                      # scored there again
                best_score, evals = evaluate.score(best), evals + 1
            measured = evaluate.measure_many(x.reshape(shape))                         # the population in one call
            f = np.array([m.score for m in measured])
            order = np.argsort(-f, kind="stable")                                      # best first, ties by index
            evals += self.lam
            if f[order[0]] > best_score or (evaluate.fresh and f[order[0]] == best_score):   # the best so far
                best, best_score = x[order[0]].reshape(shape[1:]), float(f[order[0]])
                observer.accepted(generation + t + 1, best, best_score, True, measured[order[0]].final_xy)
            yw = self.weights @ y[order[:mu]]                                          # the best mu, log weights
            mean = mean + sigma * yw
            ps = (1 - self.cs) * ps + math.sqrt(self.cs * (2 - self.cs) * self.mueff) * yw / np.sqrt(diag)
            gen += 1
            norm = float(np.linalg.norm(ps))
            hsig = norm / math.sqrt(1 - (1 - self.cs) ** (2 * gen)) / self.chin < 1.4 + 2 / (self.n + 1)
            pc = (1 - self.cc) * pc + hsig * math.sqrt(self.cc * (2 - self.cc) * self.mueff) * yw
            diag = ((1 - self.c1 - self.cmu) * diag
                    + self.c1 * (pc * pc + (1 - hsig) * self.cc * (2 - self.cc) * diag)
                    + self.cmu * (self.weights @ (y[order[:mu]] ** 2)))
            sigma *= math.exp(self.cs / self.damps * (norm / self.chin - 1))
            score[t], h["team_evals"][t], h["sigma"][t] = best_score, evals, sigma
        return SepCMAState(mean=mean, diag=diag, ps=ps, pc=pc, sigma=sigma, gen=gen, best=best, score=best_score,
                           evals=evals, rng=rng.bit_generator.state), {"score": score, **h}
