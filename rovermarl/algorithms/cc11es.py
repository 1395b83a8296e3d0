"""CC-(1+1)-ES (SPEC section 6): each rover owns a (1+1)-ES; each generation mutates k of them together and keeps
all k children or none, on the team's shared score. Its operators are config groups of their own: ``k`` (fixed or a
k-selector such as EXP3), ``team``, ``mutation`` and ``selection``. Run state: :class:`CC11ESState`.

The generation loop is :func:`rovermarl.algorithms.generation.generations`, its one source, run over :data:`PYTHON`
(any operator, as Python) or :data:`rovermarl.algorithms.compiled.COMPILED` (the packaged operators, compiled,
bit-identical): ``algorithm.loop`` chooses (``auto``, the default: compiled wherever it applies; ``compiled`` is
refused in one line elsewhere). docs/ARCHITECTURE.md, "One generation, top to bottom", walks through it.
"""

from __future__ import annotations

import copy
import inspect
from dataclasses import dataclass
from types import SimpleNamespace

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
from rovermarl.algorithms.generation import NO_PROBS, Context, Ops, generations


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
    """Built from ``conf/algorithm/cc11es.yaml``: the ``k``, ``selection``, ``team`` and ``mutation`` nodes and the
    initial genome range (``policy.init_low``, ``policy.init_high``). Under ``evaluation.fresh_ic`` every generation
    scores the parents again on the child's fresh initial conditions, so selection compares the two on one draw;
    ``score`` is then the kept team's F on that draw."""

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
        selector = copy.deepcopy(self.selector)                              # the chunk's copy, in the run's state
        selector.load_state_dict(state.selector)
        rng_mut, rng_sel = generator(state.rng_mut), generator(state.rng_sel)
        parents, f_parent = np.array(state.parents, dtype=np.float64), float(state.score)
        h = {"score": np.empty(n), **{s.name: s.empty(n) for s in self.series}}
        out = (h["score"], h["k"], h["accepted"], h["switched"], h["child_score"], h.get("probs", NO_PROBS))
        compiled_loop = self._compiled(evaluate)
        if compiled_loop:
            run = compiled.loop_of(evaluate.kernel_inputs().world.compiled).run
            args = compiled.arguments(self, selector, rng_mut, rng_sel, parents, evaluate, observer)
        else:
            run, cx = _python_run, _python_context(self, selector, rng_mut, rng_sel, evaluate, observer, generation)
            args = (cx,)
        t = 0
        while t < n:                              # a call stops after a generation that keeps its children
            t, f_parent, f_before = run(t, n, parents, f_parent, *out, *args)
            if h["accepted"][t - 1]:                                          # 7. the observer logs the change
                final_xy = evaluate.kernel_inputs().final_xy if compiled_loop else cx.evaluation.final_xy
                observer.accepted(generation + t, self.composition.genomes(parents.copy()), f_parent,
                                  f_parent != f_before, None if final_xy is None else final_xy.copy())
        if compiled_loop:
            compiled.finish(selector, evaluate, n)
        return CC11ESState(parents=parents, score=f_parent, rng_mut=rng_mut.bit_generator.state,
                           rng_sel=rng_sel.bit_generator.state, selector=selector.state_dict()), h

    def _compiled(self, evaluate) -> bool:
        """Whether this chunk runs compiled (``algorithm.loop``; ``compiled`` where it does not apply: refused)."""
        if self.loop == "python":
            return False
        why = compiled.refusal(self, evaluate.fresh, evaluate.kernel_inputs() is not None)
        if why is not None and self.loop == "compiled":
            raise AlgorithmError(f"algorithm.loop=compiled: {why}")
        return why is None

    def allowed_k(self, k, selector) -> int:
        """``k`` if the selector may choose it (its arms, within 1..N), else :class:`AlgorithmError`."""
        if k not in self.allowed or isinstance(k, bool):
            cls = type(selector)
            raise AlgorithmError(f"k-selector {cls.__module__}.{cls.__qualname__} ({inspect.getsourcefile(cls)}) "
                                 f"chose k={k!r}; allowed: {', '.join(map(str, sorted(self.allowed)))} (its arms "
                                 f"within 1..N={self.world.n_rovers})")
        return k


def _python_context(algo, selector, rng_mut, rng_sel, evaluate, observer, generation) -> Context:
    """The Python operations' context for a chunk of CC11ES ``algo`` (a generation.Context);
    ``evaluation.final_xy``: the last team's final positions (E, N, 2) as the evaluation measured them."""
    team = algo.composition
    evaluation = SimpleNamespace(evaluate=evaluate, composition=team, generation=generation, final_xy=None)
    return Context(k=SimpleNamespace(selector=selector, rng=rng_sel, allowed=algo.allowed_k),
                   team=SimpleNamespace(composition=team, mutate=algo.mutate, rng=rng_mut),
                   evaluation=evaluation,
                   observer=SimpleNamespace(observer=observer, composition=team, evaluation=evaluation),
                   selection=algo.accept)


def _choose(k, t, out_probs):
    if out_probs.shape[0]:
        out_probs[t] = k.selector.probs                                       # before this generation's choice
    chosen = k.allowed(k.selector.choose(k.rng), k.selector)
    return chosen, chosen                                                     # a Python selector's arm is its k


def _mutate(team, parents, chosen):
    children = team.composition.mutate(parents, chosen, team.mutate, team.rng)
    if not isinstance(children, np.ndarray) or children.shape != parents.shape:
        cls = type(team.composition)
        raise AlgorithmError(f"team {cls.__module__}.{cls.__qualname__} ({inspect.getsourcefile(cls)}): mutate "
                             f"returned {getattr(children, 'shape', type(children).__name__)}, not an array of the "
                             f"parents' shape {parents.shape}")
    return children


def _rescore(evaluation, t, parents, f_parent):
    if not evaluation.evaluate.fresh:
        return f_parent
    evaluation.evaluate.draw(evaluation.generation + t + 1)
    return evaluation.evaluate.score(evaluation.composition.genomes(parents))


def _measure(evaluation, children):
    f, evaluation.final_xy = evaluation.evaluate.measure(evaluation.composition.genomes(children))
    return f


PYTHON = Ops(
    choose=_choose,
    pick=lambda team, k: team.composition.pick(k, team.rng),
    mutate=_mutate,
    rescore=_rescore,
    measure=_measure,
    switched=lambda obs, chosen: obs.observer.evaluated(obs.composition.mutated(chosen), obs.evaluation.final_xy),
    accept=lambda accept, f_child, f_parent: accept(f_child, f_parent),
    reward=lambda k, a, chosen, f_child, f_parent: k.selector.update(chosen, f_child, f_parent),
    keep=np.copyto,
)


def _python_run(t, n, parents, f_parent, out_score, out_k, out_accepted, out_switched, out_child, out_probs, cx):
    """:func:`~rovermarl.algorithms.generation.generations` over :data:`PYTHON` and ``cx``
    (:func:`_python_context`), run as Python."""
    return generations.py_func(t, n, parents, f_parent, PYTHON, cx, out_score, out_k, out_accepted, out_switched,
                               out_child, out_probs)
