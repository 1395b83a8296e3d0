"""The two training regimes' and the final team's rules, one source each: :func:`keep_best` (``final_team=best``:
the kept team and a new one on the same starts), :func:`score_iterate` (how a learner that steps environments itself
scores its iterate), :func:`train_starts` (the starts it trains on: the run's own, or fresh ones), and
:class:`SharedActor`, the base of those learners (PPO, MAPPO, IPPO)."""

from __future__ import annotations

import numpy as np

from rovermarl import errors
from rovermarl.algorithms.base import Algorithm, Evaluator, Measured, RunState, python_loop
from rovermarl.env import InitialConditions

FINAL_TEAMS = ("last", "best")


class SharedActor(Algorithm):
    """A learner whose team is N copies of one actor's deterministic policy, which it trains by stepping
    environments itself (PPO, MAPPO, IPPO): the final-team rule over its iterates. A subclass sets
    :attr:`final_team` (one of :data:`FINAL_TEAMS`) and gives ``_genomes(params) -> (N, P)``; the kept iterate's
    genome (P,) is ``state.best`` under ``best``."""

    fresh_ic = True    # evaluation.fresh_ic: trains and scores on fresh starts (else on the run's own, in turn)
    kernel_calls = ("observe", "env_step")                # its environments' steps (rovermarl.vector.VectorEnv)

    def _genomes(self, params) -> np.ndarray:
        raise NotImplementedError

    def _common_keys(self, loop: str, final_team: str, num_envs: int, n_steps: int, what: str = "") -> None:
        """Check the keys every such learner takes; ``n_steps`` a multiple of ``env.steps`` (each ``what`` iteration
        starts on fresh episodes)."""
        python_loop(loop, type(self).__name__)
        self.final_team = errors.choice("final_team", final_team, FINAL_TEAMS)
        self.num_envs = errors.integer("num_envs", num_envs, 1, 1_000_000)
        self.n_steps = errors.integer("n_steps", n_steps, self.world.steps, 1_000_000)
        if self.n_steps % self.world.steps:
            raise errors.ConfigError("n_steps", n_steps, f"must be a multiple of env.steps={self.world.steps} (each "
                                     f"{what}iteration starts on fresh episodes)")

    def check_run(self, fresh_ic: bool, local: bool) -> None:
        if not fresh_ic and not local:
            raise errors.ConfigError("parallel.ic_shards", "> 1", f"{type(self).__name__} trains on the run's initial "
                                     "conditions in its own process under evaluation.fresh_ic=false: use "
                                     "parallel.ic_shards=1")

    def evaluations_per_generation(self, fresh_ic: bool = False) -> float:
        """One iteration's steps in team evaluations (``num_envs * n_steps`` environment steps of N agents)."""
        return self.num_envs * self.n_steps / (self.world.episodes * self.world.steps)

    def agent_steps_per_generation(self, fresh_ic: bool = False) -> int:
        return self.num_envs * self.n_steps * self.world.n_rovers

    def own_agent_steps_per_generation(self, fresh_ic: bool = False) -> int:
        """Every training step is its own (its team's scoring each generation is a team evaluation besides)."""
        return self.agent_steps_per_generation(fresh_ic)

    def _first(self, state: RunState, evaluate: Evaluator) -> Measured:
        """Score the first iterate; ``state`` gets its ``score`` (and ``best``)."""
        team = self._genomes(state.params)
        measured = evaluate.measure(team)
        state.score = measured.score
        if self.final_team == "best":
            state.best = team[0].copy()
        return measured

    def _team(self, state):
        if self.final_team == "best":                                     # the kept iterate's team
            return self.world.homogeneous(np.asarray(state.best, dtype=np.float64))
        return self._genomes(state.params)

    def _scored(self, state: RunState, best, evaluate: Evaluator, generation: int, kept_score: float):
        """Score the new iterate in ``state`` (its ``params``) at the end of ``generation`` against the kept one,
        whose genome (P,) is ``best`` (None under ``last``) and score ``kept_score`` (:func:`score_iterate`);
        ``state.best`` becomes the genome kept. Returns ``(team, Measured)``."""
        kept = None if best is None else self.world.homogeneous(np.asarray(best, dtype=np.float64))
        team, measured = score_iterate(evaluate, generation, self._genomes(state.params), kept, kept_score)
        if kept is not None:
            state.best = team[0].copy()
        return team, measured


def keep_best(evaluate: Evaluator, kept: np.ndarray, kept_score: float, team: np.ndarray, measured: Measured):
    """The final-team rule ``best``, its one source: the new ``team`` (N, P) scored ``measured`` replaces the ``kept``
    one (N, P) when it scores at least as well on the same initial conditions (under ``evaluation.fresh_ic`` the kept
    one is scored again on this generation's, beside it: one more team evaluation; else ``kept_score`` is its
    score). Returns the team kept with its score and final positions: ``(team, Measured)``."""
    if evaluate.fresh:
        kept_score = evaluate.score(kept)
    if measured.score >= kept_score:
        return team, measured
    return kept, Measured(float(kept_score), None)


def score_iterate(evaluate: Evaluator, generation: int, team: np.ndarray, kept: np.ndarray | None,
                  kept_score: float):
    """How a learner that steps environments itself scores its iterate ``team`` (N, P) at the end of ``generation``:
    on that generation's starts under ``evaluation.fresh_ic``, against the ``kept`` team (N, P; None: ``last``) by
    :func:`keep_best`. Returns ``(team, Measured)``: the run's team after the generation."""
    if evaluate.fresh:
        evaluate.draw(generation)
    measured = evaluate.measure(team)
    return (team, measured) if kept is None else keep_best(evaluate, kept, kept_score, team, measured)


def train_starts(evaluate: Evaluator) -> InitialConditions | None:
    """The starts a learner that steps environments itself trains on, in turn: the run's own under
    ``evaluation.fresh_ic=false`` (``fixed``), None under ``fresh`` (its environments draw new ones)."""
    if evaluate.fresh:
        return None
    inputs = evaluate.kernel_inputs()
    if inputs is None:
        raise errors.ConfigError("evaluation.fresh_ic", False, "this learner needs the run's initial conditions in "
                                 "its own process to train on them (use parallel.ic_shards=1)")
    return inputs.ic
