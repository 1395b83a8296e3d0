"""CC-(1+1)-ES's generation loop (SPEC section 6), its one source: steps 1-7 of each generation over the operations
``ops`` (:class:`Ops`) on a context ``cx``, either :data:`rovermarl.algorithms.cc11es.PYTHON` (any operator objects,
run as ``generations.py_func``) or :data:`rovermarl.algorithms.compiled.COMPILED` (numba functions, compiled into
``compiled.run``: numba compiles a function passed as an argument into its caller). docs/ARCHITECTURE.md, "One
generation, top to bottom".

A call runs generations t..n-1 and returns after the first that keeps its children, so that the caller tells the
observer (step 7).
"""

from __future__ import annotations

from collections import namedtuple
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from rovermarl.jit import njit

NO_PROBS = np.empty((0, 1))     # out_probs of a selector without probabilities
Context = namedtuple("Context", "k team evaluation observer selection")   # cx: what each operator's operations read


class Ops(NamedTuple):
    """What a generation does, each a function of its part of the context ``cx`` first (``cx.k``, ``cx.team``,
    ``cx.evaluation``, ``cx.observer``, ``cx.selection``; shapes: parents and children (M, P), M = N or 1 for a
    homogeneous team; ``out_probs`` (n, K), or (0, 1) when the selector has no probabilities)."""

    choose: Callable    # (cx.k, t, out_probs) -> (a, k): generation t's k (the selector's arm a); its probabilities
    #                     before the choice to out_probs[t]
    pick: Callable      # (cx.team, k) -> chosen (k,) int: the parents to mutate
    mutate: Callable    # (cx.team, parents, chosen) -> children: the parents, each chosen one mutated
    rescore: Callable   # (cx.evaluation, t, parents, f_parent) -> the parents' score on generation t's initial
    #                     conditions (fresh ones drawn under evaluation.fresh_ic; else f_parent)
    measure: Callable   # (cx.evaluation, children) -> F of the team the children make (its final positions kept in
    #                     cx.evaluation.final_xy)
    switched: Callable  # (cx.observer, chosen) -> episodes in which an unmutated rover ends at another POI (-1: not
    #                     measured)
    accept: Callable    # (cx.selection, f_child, f_parent) -> whether the children are kept
    reward: Callable    # (cx.k, a, k, f_child, f_parent) -> None: the selector learns from the generation
    keep: Callable      # (parents, children) -> None: parents[...] = children


@njit(inline="always", cache=True)
def generations(t, n, parents, f_parent, ops, cx, out_score, out_k, out_accepted, out_switched, out_child, out_probs):
    """Generations t..n-1 of a chunk, up to and including the first that keeps its children; returns the next t,
    the parents' score and the score they had before that generation (the caller's ``score_changed``).
    ``parents`` (M, P) changes in place; each generation's score, k, acceptance, switched count and child score go
    to the ``out_*`` arrays (n,)."""
    while t < n:
        a, k = ops.choose(cx.k, t, out_probs)                           # 1. choose k
        chosen = ops.pick(cx.team, k)                                   # 2. k distinct rovers
        children = ops.mutate(cx.team, parents, chosen)                 # 3. mutate them
        f_parent = ops.rescore(cx.evaluation, t, parents, f_parent)     #    fresh initial conditions: parents on them
        f_child = ops.measure(cx.evaluation, children)                  # 4. evaluate the team
        out_switched[t] = ops.switched(cx.observer, chosen)             #    did unmutated rovers switch POI?
        accepted = ops.accept(cx.selection, f_child, f_parent)          # 5. all k children or none
        ops.reward(cx.k, a, k, f_child, f_parent)                       # 6. reward the selector
        f_before = f_parent
        if accepted:
            ops.keep(parents, children)
            f_parent = f_child
        out_k[t], out_accepted[t], out_child[t], out_score[t] = k, accepted, f_child, f_parent
        t += 1
        if accepted:                                        # 7. the caller tells the observer
            return t, f_parent, f_before
    return t, f_parent, f_parent
