"""The compiled generation loop (rovermarl.algorithms.compiled) against the Python loop of CC11ES: same arrays,
events, states and evaluation counts, bit for bit, for every configuration ``algorithm.loop=auto`` sends to it; chosen
only where it applies, and ``algorithm.loop=compiled`` refused in one line elsewhere."""

import itertools
import sys

import numpy as np
import pytest

from rovermarl import errors
from rovermarl.algorithms import compiled
from rovermarl.algorithms.operators.mutation import MixedMutation, mixed
from rovermarl.algorithms.operators.selection import Selection
from rovermarl.algorithms.operators.selectors import EXP3, FixedK
from rovermarl.algorithms.operators.team import HeterogeneousTeam, HomogeneousTeam, pick_distinct
from rovermarl.env.kernel import pairwise_sum, score
from rovermarl.runner.chunk import Run, to_plain
from rovermarl.runner.validate import validate
from tests.conftest import ROOT, make_cfg

# Each operator class the compiled loop runs (compiled.OPERATORS), as the overrides that choose it ...
CLASSES = {FixedK: ["k=2"], EXP3: ["k=adaptive"], MixedMutation: [], Selection: [], HeterogeneousTeam: [],
           HomogeneousTeam: ["team=homogeneous"]}
# ... and the other choices the compiled loop takes as they are: the selection rule, the precision, the observer.
CHOICES = ((["selection=soft"], ["selection=strict"]), ([], ["env.dtype=float32"]), ([], ["record.occupancy=false"]))
EVERY = [sum(combo, []) for combo in itertools.product(
    *([CLASSES[c] for c in classes] for classes in compiled.OPERATORS.values()), *CHOICES)]
MORE = [                                         # other values of the operators' parameters and of the world
    ["k=1"], ["k=adaptive", "setup=duo"], ["k=4"],
    ["k=adaptive", "k.reward=gain", "k.arms=[1,3]", "mutation.p_gaussian=0.5"],
    ["k=3", "env.reward=any_step", "env.speed=clip", "env.episodes=9"],
    ["k=adaptive", "setup=duo", "env.dtype=float32"],
]


def test_every_class_the_compiled_loop_runs_has_its_configurations_here():
    assert {c for classes in compiled.OPERATORS.values() for c in classes} == set(CLASSES)
    assert len(EVERY) == 32


def _run(overrides, loop, monkeypatch, seed=1, chunks=(700, 500)):
    """Chunks of a run under ``algorithm.loop=loop``; returns (arrays, events, state, evaluations, compiled
    calls)."""
    cfg = to_plain(make_cfg(*overrides, "generations=1200", f"algorithm.loop={loop}"))
    calls = []
    real = compiled.run
    monkeypatch.setattr(compiled, "run", lambda *a: calls.append(1) or real(*a))
    run = Run(cfg, seed)
    arrays = [run.advance(n) for n in chunks]
    resumed = Run(cfg, seed, state=run.state())                   # a chunk after a resume, too
    arrays.append(resumed.advance(300))
    return arrays, [run.observer.drain(), resumed.observer.drain()], resumed.state(), run.evaluate.calls, len(calls)


def _assert_same(a, b, path="run"):
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for key in a:
            _assert_same(a[key], b[key], f"{path}.{key}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype, path
        np.testing.assert_array_equal(a, b, err_msg=path)
    else:
        assert a == b, path


@pytest.mark.parametrize("overrides", EVERY + MORE)
def test_compiled_loop_gives_the_python_loops_run(overrides, monkeypatch):
    run = Run(to_plain(make_cfg(*overrides, "generations=10")), 0)
    assert compiled.refusal(run.parts.algorithm, run.evaluate.fresh, True) is None      # auto takes the compiled loop
    py = _run(overrides, "python", monkeypatch)
    jit = _run(overrides, "auto", monkeypatch)
    assert py[4] == 0 and jit[4] > 1                             # each loop ran as forced
    assert jit[0][0]["accepted"].any()                           # accepted generations crossed compiled calls
    _assert_same(py[:4], jit[:4])


@pytest.mark.parametrize("overrides", [["+env._target_=examples.obstacles.obstacles.Obstacles", "k=2"],
                                       ["+env._target_=examples.moving_pois.moving_pois.MovingPois", "k=adaptive"]])
def test_a_plugin_world_runs_the_compiled_loop_and_gets_the_python_loops_run(overrides, monkeypatch):
    sys.path.insert(0, str(ROOT))
    run = Run(to_plain(make_cfg(*overrides, "generations=10")), 0)
    assert compiled.refusal(run.parts.algorithm, run.evaluate.fresh, True) is None
    world = run.parts.algorithm.world
    assert compiled.loop_of(world.compiled).__name__.startswith("rovermarl_loop_")
    py = _run(overrides, "python", monkeypatch)
    calls = []
    copy = compiled.loop_of(world.compiled)
    real = copy.run
    monkeypatch.setattr(copy, "run", lambda *a: calls.append(1) or real(*a))
    jit = _run(overrides, "auto", monkeypatch)
    assert len(calls) > 1 and jit[0][0]["accepted"].any()
    _assert_same(py[:4], jit[:4])


class MyEXP3(EXP3):
    """A user's variant of EXP3: its rules may differ, so it takes the Python loop."""


class MyMutation(MixedMutation):
    """A user's mutation built on the mixed one."""


@pytest.mark.parametrize("overrides, target, local, expected", [
    (["k=adaptive"], None, True, True),
    (["k=2", "team=homogeneous", "selection=strict"], None, True, True),
    (["k=ucb1"], None, True, False),
    (["k=1", "evaluation.fresh_ic=true"], None, True, False),
    (["k=1"], None, False, False),                               # teams scored in other processes (IC shards)
    (["k=2"], ("mutation", "MyMutation"), True, False),
    (["k=adaptive"], ("k", "MyEXP3"), True, False),
])
def test_compiled_loop_only_where_it_applies(overrides, target, local, expected):
    cfg = make_cfg(*overrides, "generations=10")
    if target:
        cfg[target[0]]._target_ = f"{__name__}.{target[1]}"
    run = Run(to_plain(cfg), 0)
    assert (compiled.refusal(run.parts.algorithm, run.evaluate.fresh, local) is None) is expected


@pytest.mark.parametrize("overrides, why", [
    (["k=ucb1"], "runs only the packaged operators FixedK, EXP3 as selector, not "),
    (["k=1", "evaluation.fresh_ic=true"], "under evaluation.fresh_ic every generation draws new initial conditions"),
    (["k=1", "parallel.ic_shards=2"], "IC shards (parallel.ic_shards > 1) score teams in other processes"),
    (["algorithm=ccea"], "the CCEA has no compiled generation loop"),
    (["algorithm=cma"], "CMA-ES has no compiled generation loop"),
])
def test_a_compiled_loop_where_none_applies_is_refused_in_one_line(overrides, why):
    sys.path.insert(0, str(ROOT))
    with pytest.raises(errors.ConfigError) as e:
        validate(make_cfg(*overrides, "algorithm.loop=compiled"))
    assert str(e.value).startswith("algorithm.loop=compiled: ") and why in str(e.value) and "\n" not in str(e.value)
    validate(make_cfg(*overrides, "algorithm.loop=python"))      # the Python loop takes it


def test_the_loop_is_a_choice_of_three():
    with pytest.raises(errors.ConfigError, match=r"^algorithm.loop=fast: must be one of auto, python, compiled$"):
        validate(make_cfg("algorithm.loop=fast"))


def test_numba_draws_what_numpy_draws():
    """The operators' numba functions take the same numbers from a numpy Generator as numpy's own calls."""
    for seed in range(5):
        a, b = np.random.default_rng(seed), np.random.default_rng(seed)
        for _ in range(200):
            np.testing.assert_array_equal(pick_distinct(a, 4, 3), b.permutation(4)[:3])
            genome = np.linspace(-1, 1, 658)
            got = mixed(genome, a, 0.5, 0.1, 164, -2.0, 2.0)
            if b.random() < 0.5:
                want = genome + b.normal(0.0, 0.1, 658)
            else:
                u, values = b.random(164), b.uniform(-2.0, 2.0, 164)
                want = genome.copy()
                perm = np.arange(658)
                for i in range(164):
                    j = min(i + int(u[i] * (658 - i)), 657)
                    perm[i], perm[j] = perm[j], perm[i]
                    want[perm[i]] = values[i]
            np.testing.assert_array_equal(got, want)
        assert a.bit_generator.state == b.bit_generator.state


@pytest.mark.parametrize("n", [*range(1, 40), 127, 128, 129, 136, 255, 256, 1000, 4097])
def test_score_sums_in_numpys_order(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        a = rng.standard_normal(n) * 10.0 ** rng.uniform(-8, 8, n)      # spread magnitudes: the order shows
        assert pairwise_sum(a) == a.sum()
        assert score(a) == float(a.sum()) / n


def test_numpys_sum_order_is_not_the_plain_one():
    """What the test above tells apart: a plain left-to-right sum differs from numpy's."""
    a = np.random.default_rng(0).standard_normal((50, 37)) * 10.0 ** np.random.default_rng(1).uniform(-8, 8, (50, 37))
    assert any(pairwise_sum(row) != np.cumsum(row)[-1] for row in a)


def test_the_compiled_loop_is_cached_for_the_next_process():
    """numba caches no function that holds Python objects' addresses (it warns, and every process compiles again):
    the loop's operations, passed to the one loop as functions, must be resolved at compile time."""
    Run(to_plain(make_cfg("k=adaptive", "generations=20")), 0).advance(10)
    assert compiled.run.overloads
    assert not any(c.library.has_dynamic_globals for c in compiled.run.overloads.values())
