"""CC-(1+1)-ES (SPEC section 6): each rover owns a (1+1)-ES; each generation mutates k of them together and keeps
all k children or none, on the team's shared score.

Its operators are config groups of their own: ``k`` (fixed or a k-selector such as EXP3), ``team``
(heterogeneous or homogeneous), ``mutation`` and ``selection`` (soft or strict).

Run state: :class:`CC11ESState`.

``loop`` (``algorithm.loop``) chooses the generation loop: ``python`` runs :meth:`CC11ES._advance`'s steps 1-7 below,
``compiled`` the same steps in numba (:mod:`rovermarl.algorithms.compiled`, bit-identical; refused in one line where
it does not apply), ``auto`` (the default) the compiled one wherever it applies.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from rovermarl import errors
from rovermarl.algorithms import compiled
from rovermarl.algorithms.base import (
    LOOPS,
    Algorithm,
    AlgorithmError,
    RunState,
    Series,
    build_operator,
    generator,
    init_range,
)


@dataclass(kw_only=True)
class CC11ESState(RunState):
    """``parents`` (M, P) (M = N, or 1 for a homogeneous team) scored ``score``; the bit-generator states
    ``rng_mut`` (which rovers, which changes: the run's ``mutation`` stream) and ``rng_sel`` (the selector's draws:
    its ``selector`` stream); the selector's ``state_dict``."""

    parents: np.ndarray
    rng_mut: dict
    rng_sel: dict
    selector: dict


class CC11ES(Algorithm):
    """Built from ``conf/algorithm/cc11es.yaml``: the nodes of the ``k``, ``selection``, ``team`` and ``mutation``
    groups, and the initial genome range (``policy.init_low``, ``policy.init_high``).

    Under ``evaluation.fresh_ic`` every generation scores the parents again on the child's fresh initial
    conditions, so selection compares the two on one draw; ``score`` is then the kept team's F on that draw.
    """

    state_type = CC11ESState
    fresh_ic = True

    def __init__(self, world, k, selection, team, mutation, init_low: float = -2.0, init_high: float = 2.0,
                 loop: str = "auto"):
        super().__init__(world)
        self.loop = errors.choice("loop", loop, LOOPS)
        n = world.n_rovers
        self.low, self.high = init_range(init_low, init_high)
        self.composition = build_operator(team, "team", n_agents=n)
        self.mutate = build_operator(mutation, "mutation")
        self.accept = build_operator(selection, "selection")
        self.selector = build_operator(k, "k", n_agents=n, f_max=world.max_return)
        arms = tuple(self.selector.arms)
        self.allowed = frozenset(a for a in arms if 1 <= a <= n) if arms else frozenset(range(1, n + 1))
        self.series = (
            Series("k", "int16", doc="rovers mutated"),
            Series("accepted", "bool", doc="children kept"),
            Series("switched", "int16", fill=-1, doc="episodes in which an unmutated rover ends at another POI "
                                                      "than under the parents (-1: not measured)"),
            Series("child_score", "float64", fill=np.nan, doc="F of the evaluated team"),
        )
        if self.selector.probs is not None:
            self.series += (Series("probs", "float64", (len(arms),), np.nan, "the selector's probability of each k "
                                   "before the generation", tuple(f"k{a}" for a in arms), "bandit"),)
        if self.loop == "compiled":
            self.check_run(fresh_ic=False, local=True)

    def check_run(self, fresh_ic: bool, local: bool) -> None:
        why = compiled.refusal(self, fresh_ic, local) if self.loop == "compiled" else None
        if why:
            raise errors.ConfigError("loop", "compiled", why)

    def evaluations_per_generation(self, fresh_ic: bool = False) -> float:
        return 2.0 if fresh_ic else 1.0                                   # fresh ICs: the parents scored again

    def _init(self, streams, evaluate):
        parents = self.composition.init(self.world.n_params, self.low, self.high,
                                        np.random.default_rng(streams.algorithm))
        measured = evaluate.measure(self.composition.genomes(parents))
        return CC11ESState(parents=parents, score=measured.score,
                           rng_mut=np.random.default_rng(streams.mutation).bit_generator.state,
                           rng_sel=np.random.default_rng(streams.selector).bit_generator.state,
                           selector=copy.deepcopy(self.selector).state_dict()), measured

    def _team(self, state):
        return self.composition.genomes(state.parents)

    def _advance(self, state, generation, n, evaluate, observer):
        if self.loop != "python":
            why = compiled.refusal(self, evaluate.fresh, evaluate.kernel_inputs() is not None)
            if why is None:
                return compiled.advance(self, state, generation, n, evaluate, observer)
            if self.loop == "compiled":
                raise AlgorithmError(f"algorithm.loop=compiled: {why}")
        team, mutate, accept = self.composition, self.mutate, self.accept
        selector, rng_mut, rng_sel, parents, f_parent, h = self._start(state, n)
        for t in range(n):
            g = generation + t
            if "probs" in h:
                h["probs"][t] = selector.probs                                # before this generation's choice
            k = self._check(selector.choose(rng_sel), selector)               # 1. choose k
            chosen = team.pick(k, rng_mut)                                    # 2. k distinct rovers
            children = team.mutate(parents, chosen, mutate, rng_mut)          # 3. mutate them
            genomes = team.genomes(children)                                  # (N, P): the team the world sees
            if evaluate.fresh:                                                #    fresh ICs: a new draw, the
                evaluate.draw(g + 1)                                          #    parents scored on it too
                f_parent = evaluate.score(team.genomes(parents))
            f_child, final_xy = evaluate.measure(genomes)                     # 4. evaluate the team
            h["switched"][t] = observer.evaluated(team.mutated(chosen), final_xy)  # did unmutated rovers switch POI?
            accepted = accept(f_child, f_parent)                              # 5. all k children or none
            selector.update(k, f_child, f_parent)                             # 6. reward the selector
            if accepted:                                                      # 7. the observer logs the change
                observer.accepted(g + 1, genomes, f_child, f_child != f_parent, final_xy)
                parents, f_parent = children, f_child
            h["k"][t], h["accepted"][t], h["child_score"][t], h["score"][t] = k, accepted, f_child, f_parent
        return self._state(parents, f_parent, rng_mut, rng_sel, selector), h

    def _start(self, state, n):
        """The loop's working objects from run ``state``: the selector (a copy, in its state), the generators
        ``rng_mut`` and ``rng_sel``, the parents (M, P) and their score, and the arrays of ``n`` generations (the
        score and the declared series)."""
        selector = copy.deepcopy(self.selector)
        selector.load_state_dict(state.selector)
        return (selector, generator(state.rng_mut), generator(state.rng_sel),
                np.array(state.parents, dtype=np.float64), float(state.score),
                {"score": np.empty(n), **{s.name: s.empty(n) for s in self.series}})

    @staticmethod
    def _state(parents, score, rng_mut, rng_sel, selector) -> CC11ESState:
        """The run state after a chunk."""
        return CC11ESState(parents=parents, score=score, rng_mut=rng_mut.bit_generator.state,
                           rng_sel=rng_sel.bit_generator.state, selector=selector.state_dict())

    def _check(self, k, selector) -> int:
        """``k`` if the selector may choose it (its arms, within 1..N), else :class:`AlgorithmError`."""
        if k not in self.allowed or isinstance(k, bool):
            raise AlgorithmError(f"k-selector {type(selector).__name__} chose k={k!r}; allowed: "
                                 f"{', '.join(map(str, sorted(self.allowed)))} (its arms within 1..N="
                                 f"{self.world.n_rovers})")
        return k
