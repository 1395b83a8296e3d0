"""CC-(1+1)-ES's generation loop compiled (numba) for its common operators, bit-identical to the Python loop of
:mod:`rovermarl.algorithms.cc11es`, which stays for every other plug-in.

The common case: k fixed or EXP3 (``k=1..N``, ``k=adaptive``), the mixed mutation, soft or strict selection, a
heterogeneous or homogeneous team (exactly the classes of :data:`OPERATORS`), in any world (a plug-in's: a copy of
this module's loop around its own rollout, :func:`loop_of`), scored in this process on the run's initial conditions
(not fresh ones, not IC shards). :func:`refusal` says why a run is not in it (None:
it is); ``algorithm.loop`` chooses (``auto``: this loop wherever it applies).

Both loops run the same rules: the compiled one calls the operators' own numba functions (``draw_arm``,
``exp3_update``, ``bandit_reward``, ``pick_distinct``, ``mixed``, ``keeps``), the world's kernel and its
:func:`~rovermarl.env.kernel.score`, and numba draws the same numbers from a numpy ``Generator`` as numpy does.
Accepted generations are rare (1 in 196 with k=1 and 1 in 147 with EXP3 in 20,000-generation runs on solo), so
the compiled call stops after each one and Python tells the observer (trajectories, occupancy), then calls again.

Why a second loop: a generation's team evaluation is about 45 us of compiled work, and the Python loop adds its
operators' calls to each. ``python benchmarks/loop.py`` (500-generation chunks, alternated, medians of 7) gave the
compiled loop 1.39x (solo, k=1) and 1.61x (duo, adaptive) at load 0.8, and 1.52x and 1.75x at load 7.8, on this
2-core machine (2026-12-07). Its rules are the operators' own numba functions, which their Python classes call too,
and ``tests/test_compiled_loop.py`` holds the two loops to the same bits for every packaged operator.
"""

from __future__ import annotations

import functools
import hashlib
import sys
from pathlib import Path

import numpy as np

from rovermarl import jit
from rovermarl.algorithms.operators.mutation import MixedMutation, mixed
from rovermarl.algorithms.operators.selection import Selection, keeps
from rovermarl.algorithms.operators.selectors import EXP3, FixedK, bandit_reward, draw_arm, exp3_update
from rovermarl.algorithms.operators.team import HeterogeneousTeam, HomogeneousTeam, pick_distinct
from rovermarl.env.kernel import fused, score, switched
from rovermarl.env.kernel.compose import fill, load_generated
from rovermarl.env.kernel.fused import rollout  # rollout
from rovermarl.jit import njit

_NO_FINAL = np.empty((0, 1, 2))
_NO_POI, _NO_PROBS = np.empty((0, 1), dtype=np.int16), np.empty((0, 1))


# The operator classes the compiled loop runs, by the CC11ES attribute that holds each (subclasses may change any
# rule, so they take the Python loop). tests/test_compiled_loop.py runs the differential test on each of them.
OPERATORS = {"selector": (FixedK, EXP3), "mutate": (MixedMutation,), "accept": (Selection,),
             "composition": (HeterogeneousTeam, HomogeneousTeam)}


def refusal(algo, fresh: bool, local: bool) -> str | None:
    """Why the compiled loop cannot run CC11ES ``algo`` (None: it can): under ``evaluation.fresh_ic`` (``fresh``),
    with teams not scored in this process (``local`` false: IC shards), or with an operator that is not exactly one
    of :data:`OPERATORS`."""
    ops = {"selector": algo.selector, "mutate": algo.mutate, "accept": algo.accept, "composition": algo.composition}
    for attr, op in ops.items():
        classes = OPERATORS[attr]
        if type(op) not in classes:
            return (f"it runs only the packaged operators {', '.join(c.__name__ for c in classes)} as "
                    f"{attr}, not {type(op).__module__}.{type(op).__name__} (the Python loop runs any)")
    if fresh:
        return "under evaluation.fresh_ic every generation draws new initial conditions; the compiled loop scores " \
               "on fixed ones"
    if not local:
        return "IC shards (parallel.ic_shards > 1) score teams in other processes; the compiled loop scores here"
    return None


def advance(algo, state, generation: int, n: int, evaluate, observer) -> tuple:
    """:meth:`CC11ES._advance <rovermarl.algorithms.cc11es.CC11ES._advance>` in compiled chunks: the same state
    and arrays, bit for bit."""
    team, mut = algo.composition, algo.mutate
    selector, rng_mut, rng_sel, parents, f_parent, h = algo._start(state, n)
    exp3 = isinstance(selector, EXP3)
    arms = np.array(selector.arms, dtype=np.int64)
    log_w, probs = (selector.log_w, selector.probs.copy()) if exp3 else (np.zeros(1), np.ones(1))
    world, ic, final_xy = evaluate.kernel_inputs()
    args = world.kernel_args(ic)
    final = _NO_FINAL if final_xy is None else final_xy
    t = 0
    while t < n:
        probe = observer.switch_inputs()                         # (parent_poi, poi_xy, radius) or None
        parent_poi, poi_xy, radius = probe if probe is not None else (_NO_POI, world.poi_xy, 0.0)
        f_before = f_parent
        t, f_parent = loop_of(world.compiled)._generations(
            t, n, parents, f_parent, team.n_agents, isinstance(team, HomogeneousTeam),
            rng_mut, rng_sel, 0 if exp3 else selector.value, arms, selector.gamma if exp3 else 0.0,
            selector.reward_rule == "gain", selector.f_max, log_w, probs,
            mut.p_gaussian, mut.sigma, mut.n_reset(parents.shape[1]), mut.low, mut.high, algo.accept.strict,
            *args, final, parent_poi, poi_xy, radius,
            h["score"], h["k"], h["accepted"], h["switched"], h["child_score"], h.get("probs", _NO_PROBS))
        if t > 0 and h["accepted"][t - 1]:                   # the generation that stopped the call kept its team
            observer.accepted(generation + t, team.genomes(parents.copy()), f_parent, f_parent != f_before,
                              None if final_xy is None else final_xy.copy())          # its final positions
    evaluate.calls += n
    if exp3:
        selector.load_state_dict({"log_w": log_w})                  # its probabilities: the same function's
    return algo._state(parents, f_parent, rng_mut, rng_sel, selector), h


def loop_of(kernel):
    """The module whose ``_generations`` runs the world kernel ``kernel`` (``World.compiled``): this one for the
    paper world's, else a copy of this module whose ``rollout`` is the plug-in's (compiled into the loop as the paper
    world's is; ``benchmarks/plugin_loop.py`` measures the two), made by ``compose.fill`` (the import it replaces is
    asserted: a plug-in never trains with the paper's rollout)."""
    return sys.modules[__name__] if kernel is fused else _copy(kernel.__name__)


ROLLOUT_IMPORT = "from rovermarl.env.kernel.fused import rollout  # rollout\n"


@functools.cache
def _copy(world_module: str):
    stamp = Path(sys.modules[world_module].__file__).read_text().split("\n", 1)[0]     # the world's stamp line
    text = fill(Path(__file__).read_text(), __file__, {ROLLOUT_IMPORT: f"from {world_module} import rollout\n"})
    text = f"# generated by rovermarl.algorithms.compiled for {world_module}; {stamp}\n" + text
    name = f"rovermarl_loop_{hashlib.sha256(world_module.encode()).hexdigest()[:12]}"
    jit.name_compiled(name, f"CC-(1+1)-ES's compiled loop around {jit.compiled_name(world_module)}")
    return load_generated(name, text)


@njit(cache=True)
def _generations(t, n, parents, f_parent, n_rovers, homogeneous, rng_mut, rng_sel, fixed_k, arms,
                 gamma, gain, f_max, log_w, probs, p_gaussian, sigma, m, low, high, strict, xy0, h0, world, final_xy,
                 parent_poi, poi_xy, radius, out_score, out_k, out_accepted, out_switched, out_child, out_probs):
    """Generations t..n-1 of a chunk, up to and including the first that keeps its children; returns the next t
    and the parents' score. ``parents`` (M, P) and EXP3's ``log_w``, ``probs`` (K,) change in place; the
    generation's k, acceptance, switched count (-1: not measured), child score and score go to ``out_*`` (n,),
    EXP3's probabilities before its choice to ``out_probs`` (n, K). ``xy0``, ``h0``, ``world`` are
    ``World.kernel_args(ic)``: the initial conditions and the world's :class:`~rovermarl.env.kernel.KernelWorld`."""
    returns = np.empty(h0.shape[0])
    team = np.empty((n_rovers, parents.shape[1]), dtype=xy0.dtype)      # in the kernel's precision (env.dtype)
    children = np.empty_like(parents)
    mutated = np.empty(n_rovers, dtype=np.bool_)
    no_xy, no_heading = np.empty((0, 1, 1, 2)), np.empty((0, 1, 1))                 # no trajectories
    while t < n:
        a, k = 0, fixed_k                                                 # 1. choose k (arm a)
        if fixed_k == 0:
            _put_row(out_probs, t, probs)
            a = draw_arm(probs, rng_sel.random())
            k = arms[a]
        chosen = np.zeros(1, np.int64) if homogeneous else pick_distinct(rng_mut, n_rovers, k)   # 2. k rovers
        _put(children, parents)
        for i in chosen:                                                  # 3. mutate them
            _put_row(children, i, mixed(parents[i], rng_mut, p_gaussian, sigma, m, low, high))
        for r in range(n_rovers):                                         #    the team the world sees
            _put_row(team, r, children[0] if homogeneous else children[r])
        rollout(team, xy0, h0, world, returns, no_xy, no_heading, final_xy)
        f_child = score(returns)                                          # 4. evaluate the team
        mutated[:] = homogeneous
        for i in chosen:
            mutated[i] = True
        out_switched[t] = switched(final_xy, poi_xy, radius, parent_poi, mutated)
        accepted = keeps(f_child, f_parent, strict)                       # 5. all k children or none
        if fixed_k == 0:                                                  # 6. reward the selector
            exp3_update(log_w, probs, a, bandit_reward(f_child, f_parent, gain, f_max), gamma, probs)
        if accepted:
            _put(parents, children)
            f_parent = f_child
        out_k[t], out_accepted[t], out_child[t], out_score[t] = k, accepted, f_child, f_parent
        t += 1
        if accepted:                                                      # 7. Python tells the observer
            return t, f_parent
    return t, f_parent


@njit(cache=True)
def _put_row(dst, i, src):
    """dst[i] = src (dst (R, P), src (P,)), element by element: numba's slice assignment compiles a shape check with
    its message, about 1.5 s of a cold start per call site."""
    for j in range(src.shape[0]):
        dst[i, j] = src[j]


@njit(cache=True)
def _put(dst, src):
    """dst[:] = src for two (R, P) arrays, as :func:`_put_row`."""
    for i in range(src.shape[0]):
        _put_row(dst, i, src[i])
