"""CC-(1+1)-ES's generation loop (:func:`~rovermarl.algorithms.generation.generations`, its one source) compiled
over the numba functions of its common operators (:data:`COMPILED`), bit-identical to the same loop run as Python
over any operators (:data:`~rovermarl.algorithms.cc11es.PYTHON`); docs/ARCHITECTURE.md, "One generation".

It runs exactly the classes of :data:`OPERATORS` (k fixed or EXP3, the mixed mutation, soft or strict selection, either
team), in any world (a plug-in's: a copy of this module around its own rollout, :func:`loop_of`), with teams scored in
this process on the run's fixed initial conditions; :func:`refusal` says why a run is not in it. It calls the operators'
own numba functions (``draw_arm``, ``exp3_update``, ``bandit_reward``, ``pick_distinct``, ``mixed``, ``keeps``), which
their Python classes call too: hence bit-identical. numba draws the same numbers from a numpy ``Generator`` as numpy
does. Accepted generations are rare (1 in 196 with k=1 and 1 in 147 with EXP3 in 20,000-generation runs on solo), so a
compiled call stops after each one and Python tells the observer (trajectories, occupancy), then calls again.

Why compile it: a generation's team evaluation is about 45 us of compiled work, and the Python operations add their
calls to each. ``python benchmarks/loop.py`` (500-generation chunks, alternated, medians of 7) gave the compiled
loop 1.39x (solo, k=1) and 1.61x (duo, adaptive) at load 0.8, and 1.52x and 1.75x at load 7.8, on this 2-core
machine (2026-12-07); ``tests/test_compiled_loop.py`` holds the two to the same bits for every packaged operator.
"""

from __future__ import annotations

import functools
import hashlib
import sys
from collections import namedtuple
from pathlib import Path

import numpy as np

from rovermarl import jit
from rovermarl.algorithms.generation import Context, Ops, generations
from rovermarl.algorithms.operators.mutation import MixedMutation, mixed
from rovermarl.algorithms.operators.selection import Selection, keeps
from rovermarl.algorithms.operators.selectors import EXP3, FixedK, bandit_reward, draw_arm, exp3_update
from rovermarl.algorithms.operators.team import HeterogeneousTeam, HomogeneousTeam, pick_distinct
from rovermarl.env.kernel import fused, score, switched
from rovermarl.env.kernel.compose import fill, load_generated
from rovermarl.env.kernel.fused import rollout  # rollout
from rovermarl.env.prepared import NO_FINAL
from rovermarl.jit import njit

_NO_POI = np.empty((0, 1), dtype=np.int16)


# The operator classes the compiled loop runs, by the CC11ES attribute that holds each (subclasses may change any
# rule, so they take the Python loop). tests/test_compiled_loop.py runs the differential test on each of them.
OPERATORS = {"selector": (FixedK, EXP3), "mutate": (MixedMutation,), "accept": (Selection,),
             "composition": (HeterogeneousTeam, HomogeneousTeam)}


def refusal(algo, fresh: bool, local: bool) -> str | None:
    """Why the compiled loop cannot run CC11ES ``algo`` (None: it can): under ``evaluation.fresh_ic`` (``fresh``),
    with teams not scored in this process (``local`` false: IC shards), or with an operator that is not exactly one
    of :data:`OPERATORS`."""
    for attr, classes in OPERATORS.items():
        op = getattr(algo, attr)
        if type(op) not in classes:
            return (f"it runs only the packaged operators {', '.join(c.__name__ for c in classes)} as "
                    f"{attr}, not {type(op).__module__}.{type(op).__name__} (the Python loop runs any)")
    if fresh:
        return "under evaluation.fresh_ic every generation draws new initial conditions; the compiled loop scores " \
               "on fixed ones"
    if not local:
        return "IC shards (parallel.ic_shards > 1) score teams in other processes; the compiled loop scores here"
    return None


# The compiled operations' context (generation.Context), a part per operator; run builds it from its arguments.
KSelector = namedtuple("KSelector", "rng fixed_k arms gamma gain f_max log_w probs")
TeamMutation = namedtuple("TeamMutation", "rng n_rovers homogeneous p_gaussian sigma m low high children")
Evaluation = namedtuple("Evaluation", "n_rovers homogeneous xy0 h0 world returns final_xy team no_xy no_heading")
Switches = namedtuple("Switches", "homogeneous final_xy mutated parent_poi poi_xy radius")


def arguments(algo, selector, rng_mut, rng_sel, parents, evaluate, observer) -> tuple:
    """:func:`run`'s arguments after the loop's own, for a chunk of CC11ES ``algo`` (numba types plain arguments
    quickly: a call returns to Python after each accepted generation, and a tuple of them took 200 us to dispatch
    where these take 13)."""
    team, mut, n = algo.composition, algo.mutate, algo.composition.n_agents
    exp3 = isinstance(selector, EXP3)
    world, ic, final_xy = evaluate.kernel_inputs()
    xy0, h0, kernel_world = world.kernel_args(ic)
    probe = observer.switch_inputs()                         # (parent_poi, poi_xy, radius) or None
    parent_poi, poi_xy, radius = probe if probe is not None else (_NO_POI, world.poi_xy, 0.0)
    return (rng_sel, 0 if exp3 else selector.value, np.array(selector.arms, dtype=np.int64),
            selector.gamma if exp3 else 0.0, selector.reward_rule == "gain", selector.f_max,
            *((selector.log_w, selector.probs.copy()) if exp3 else (np.zeros(1), np.ones(1))),
            rng_mut, n, isinstance(team, HomogeneousTeam), mut.p_gaussian, mut.sigma, mut.n_reset(parents.shape[1]),
            mut.low, mut.high, np.empty_like(parents),
            xy0, h0, kernel_world, np.empty(h0.shape[0]), NO_FINAL if final_xy is None else final_xy,
            np.empty((n, parents.shape[1]), dtype=xy0.dtype),           # in the kernel's precision (env.dtype)
            np.empty((0, 1, 1, 2)), np.empty((0, 1, 1)),
            np.empty(n, dtype=np.bool_), parent_poi, poi_xy, radius, algo.accept.strict)


def finish(selector, evaluate, n: int) -> None:
    """After a compiled chunk of ``n`` generations: the evaluations it made counted, EXP3's weights (changed in
    place) loaded again (its probabilities: the same function's)."""
    evaluate.calls += n
    if isinstance(selector, EXP3):
        selector.load_state_dict({"log_w": selector.log_w})


def loop_of(kernel):
    """The module whose :func:`run` runs the world kernel ``kernel`` (``World.compiled``): this one for the paper
    world's, else a copy whose ``rollout`` is the plug-in's (``benchmarks/plugin_loop.py`` measures the two), made by
    ``compose.fill`` (the import it replaces is asserted: a plug-in never trains with the paper's rollout)."""
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


@njit(inline="always", cache=True)
def _choose(k, t, out_probs):
    if k.fixed_k:
        return 0, k.fixed_k
    _put_row(out_probs, t, k.probs)
    a = draw_arm(k.probs, k.rng.random())
    return a, k.arms[a]


@njit(inline="always", cache=True)
def _pick(team, k):
    return np.zeros(1, np.int64) if team.homogeneous else pick_distinct(team.rng, team.n_rovers, k)


@njit(inline="always", cache=True)
def _mutate(team, parents, chosen):
    _put(team.children, parents)
    for i in chosen:
        _put_row(team.children, i, mixed(parents[i], team.rng, team.p_gaussian, team.sigma, team.m, team.low,
                                         team.high))
    return team.children


@njit(inline="always", cache=True)
def _rescore(evaluation, t, parents, f_parent):
    return f_parent                                          # fixed initial conditions (refusal: no fresh ones)


@njit(inline="always", cache=True)
def _measure(ev, children):
    for r in range(ev.n_rovers):                             # the team the world sees
        _put_row(ev.team, r, children[0] if ev.homogeneous else children[r])
    rollout(ev.team, ev.xy0, ev.h0, ev.world, ev.returns, ev.no_xy, ev.no_heading, ev.final_xy)
    return score(ev.returns)


@njit(inline="always", cache=True)
def _switched(obs, chosen):
    obs.mutated[:] = obs.homogeneous
    for i in chosen:
        obs.mutated[i] = True
    return switched(obs.final_xy, obs.poi_xy, obs.radius, obs.parent_poi, obs.mutated)


@njit(inline="always", cache=True)
def _accept(strict, f_child, f_parent):
    return keeps(f_child, f_parent, strict)


@njit(inline="always", cache=True)
def _reward(k, a, k_chosen, f_child, f_parent):
    if k.fixed_k == 0:
        exp3_update(k.log_w, k.probs, a, bandit_reward(f_child, f_parent, k.gain, k.f_max), k.gamma, k.probs)


@njit(inline="always", cache=True)
def _keep(parents, children):
    _put(parents, children)


COMPILED = Ops(_choose, _pick, _mutate, _rescore, _measure, _switched, _accept, _reward, _keep)


@njit(cache=True)
def run(t, n, parents, f_parent, out_score, out_k, out_accepted, out_switched, out_child, out_probs,
        rng_sel, fixed_k, arms, gamma, gain, f_max, log_w, probs,
        rng_mut, n_rovers, homogeneous, p_gaussian, sigma, m, low, high, children,
        xy0, h0, world, returns, final_xy, team, no_xy, no_heading,
        mutated, parent_poi, poi_xy, radius, strict):
    """:func:`~rovermarl.algorithms.generation.generations` over :data:`COMPILED`, its context built from
    :func:`arguments`: :class:`KSelector` (``fixed_k`` 0: EXP3, whose ``log_w`` and ``probs`` (K,) change in place),
    :class:`TeamMutation` (work array ``children`` (M, P)), :class:`Evaluation` (``World.kernel_args``; outputs
    ``returns`` (E,) and ``final_xy`` (E, N, 2), (0, 1, 2): none kept; work array ``team`` (N, P); no trajectories),
    :class:`Switches` (work array ``mutated`` (N,); the observer's ``parent_poi`` (E, N)) and ``strict``."""
    cx = Context(KSelector(rng_sel, fixed_k, arms, gamma, gain, f_max, log_w, probs),
                 TeamMutation(rng_mut, n_rovers, homogeneous, p_gaussian, sigma, m, low, high, children),
                 Evaluation(n_rovers, homogeneous, xy0, h0, world, returns, final_xy, team, no_xy, no_heading),
                 Switches(homogeneous, final_xy, mutated, parent_poi, poi_xy, radius), strict)
    return generations(t, n, parents, f_parent, COMPILED, cx, out_score, out_k, out_accepted, out_switched,
                       out_child, out_probs)


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
