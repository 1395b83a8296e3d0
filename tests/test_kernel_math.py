"""The kernel's own elementary functions against libm, and its stages against the fused rollout (bit for bit)."""

import doctest
import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from kernel_helpers import act_plain, atan2_array, atan2_ranged_array, tanh_array, tanh_finite_array

from rovermarl import make_world
from rovermarl.env import kernel
from rovermarl.env.kernel import checks, fused, rules, stages
from rovermarl.env.kernel.math import RANGED_MAX, RANGED_MIN

RNG = np.random.default_rng(12345)
N = 100_000
EDGE = [0.0, -0.0, 1.0, -1.0, 0.5, -3.0, 5e-324, -5e-324, 1e-310, 2.2250738585072014e-308, 1e-200, 1e200,
        1.7976931348623157e308, -1.7976931348623157e308, math.pi, -math.pi, math.inf, -math.inf]


def ulps(got, want):
    """Error of got in units in the last place of want (elementwise)."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    both_inf = np.isinf(want) & (got == want)
    with np.errstate(over="ignore", invalid="ignore"):
        err = np.abs(got - want) / np.spacing(np.abs(np.where(np.isinf(want), 1.0, want)))
    return np.where(both_inf | (got == want), 0.0, err)


def libm(f, *args):
    return np.array([f(*a) for a in zip(*args, strict=True)])


def same_sign_zero(got, want):
    got, want = np.asarray(got), np.asarray(want)
    zero = want == 0
    return np.array_equal(np.signbit(got[zero]), np.signbit(want[zero]))


def atan2_cases():
    y = np.concatenate([RNG.uniform(-1, 1, N), RNG.standard_normal(N) * 10.0 ** RNG.uniform(-300, 300, N),
                        RNG.standard_normal(N // 4) * 1e-310, RNG.uniform(-50, 50, N // 4)])
    x = np.concatenate([RNG.uniform(-1, 1, N), RNG.standard_normal(N) * 10.0 ** RNG.uniform(-300, 300, N),
                        RNG.standard_normal(N // 4) * 1e-310, RNG.uniform(-50, 50, N // 4)])
    x[-N // 8:] = y[-N // 8:] * (1 + RNG.normal(0, 1e-3, N // 8))          # near the diagonals
    axis = np.array(EDGE)
    ey, ex = np.meshgrid(axis, axis)
    return np.concatenate([y, ey.ravel()]), np.concatenate([x, ex.ravel()])


def test_atan2_within_2_ulp_of_libm():
    y, x = atan2_cases()
    got = np.empty_like(y)
    atan2_array(y, x, got)
    want = libm(math.atan2, y, x)
    assert ulps(got, want).max() <= 2
    assert same_sign_zero(got, want)
    assert kernel.atan2(0.0, -1.0) == math.pi and kernel.atan2(-0.0, -1.0) == -math.pi   # scalar call too
    assert kernel.atan2(1.0, 0.0) == math.pi / 2 and kernel.atan2(-1.0, -0.0) == -math.pi / 2
    assert all(math.isnan(kernel.atan2(a, b)) for a, b in ((math.nan, 1.0), (0.0, math.nan), (math.inf, math.nan)))


def test_tanh_within_2_ulp_of_libm():
    x = np.concatenate([RNG.uniform(-1, 1, N), RNG.uniform(-25, 25, N), 0.625 + RNG.uniform(-1e-3, 1e-3, N // 4),
                        RNG.choice([-1, 1], N) * 10.0 ** RNG.uniform(-320, 3, N), EDGE, [19.06, 20.0, 40.0, -710.0]])
    got = np.empty_like(x)
    tanh_array(x, got)
    want = libm(math.tanh, x)
    assert ulps(got, want).max() <= 2
    assert same_sign_zero(got, want)
    assert math.isnan(kernel.tanh(math.nan))


def test_sincos_within_2_ulp_of_libm():
    a = np.concatenate([RNG.uniform(-4, 4, N), RNG.uniform(-40, 40, N), RNG.uniform(-1e5, 1e5, N // 4),
                        RNG.choice([-1, 1], N // 4) * 10.0 ** RNG.uniform(-300, 0, N // 4),
                        [0.0, -0.0, 5e-324, math.pi, -math.pi, math.pi / 2, 1e5, -1e5]])
    near = RNG.integers(-60, 60, N // 4) * (math.pi / 2) + RNG.normal(0, 1e-9, N // 4)   # near zeros of sin/cos
    for angles in (a, near):
        s, c = np.empty_like(angles), np.empty_like(angles)
        kernel.sincos_all(angles, s, c)
        assert ulps(s, libm(math.sin, angles)).max() <= 2
        assert ulps(c, libm(math.cos, angles)).max() <= 2
    far = np.array([1e6, -3e7, 1e300, 123456.789])                          # beyond SINCOS_MAX: libm
    s, c = np.empty(4), np.empty(4)
    kernel.sincos_all(far, s, c)
    np.testing.assert_array_equal(s, np.sin(far))
    np.testing.assert_array_equal(c, np.cos(far))


def test_bearing_wraps_to_minus_pi_and_handles_zero_offset():
    h = 0.3
    c, s = math.cos(h), math.sin(h)
    b = kernel.bearing(-math.cos(h), -math.sin(h), c, s)        # straight behind: pi, read as -pi
    assert -math.pi <= b < -math.pi + 1e-15
    assert kernel.bearing(0.0, 0.0, c, s) == pytest.approx(-h, abs=1e-15)   # atan2(0, 0) - h


@pytest.mark.parametrize("dtype, lo, hi", [(np.float64, 2.0 ** -800, 2.0 ** 800), (np.float32, 2.0 ** -60, 2.0 ** 60)])
def test_ranged_atan2_gives_the_general_bits_where_it_promises(dtype, lo, hi):
    """atan2(ranged=True) leaves out the scaling, equal-magnitude and NaN cases: inside its promise (finite,
    max(|x|, |y|) in [RANGED_MIN, RANGED_MAX]; float32 [2^-60, 2^60]) it gives atan2's bits, zeros and the
    diagonals included."""
    y, x = atan2_cases()
    with np.errstate(over="ignore", under="ignore"):
        y, x = y.astype(dtype), x.astype(dtype)
    edge = np.array([lo, hi, -lo, -hi, 1.0, -1.0, 0.0, -0.0], dtype=dtype)
    ey, ex = (a.ravel() for a in np.meshgrid(edge, edge))
    y, x = np.concatenate([y, ey, x[:1000]]), np.concatenate([x, ex, -x[:1000]])    # exact diagonals too
    big = np.maximum(np.abs(x.astype(float)), np.abs(y.astype(float)))
    keep = (big >= lo) & (big <= hi)
    y, x = y[keep], x[keep]
    general, ranged = np.empty_like(y), np.empty_like(y)
    atan2_array(y, x, general)
    atan2_ranged_array(y, x, ranged)
    assert y.size > N and np.array_equal(general.view(np.uint8), ranged.view(np.uint8))
    assert dtype == np.float32 or (RANGED_MIN, RANGED_MAX) == (lo, hi)


def old_kernel():
    """The frozen copy of the 4c4ae3c kernel (benchmarks/kernel_4c4ae3c.py), whose float64 bits the kernel keeps."""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "kernel_4c4ae3c.py"
    if "kernel_4c4ae3c" in sys.modules:
        return sys.modules["kernel_4c4ae3c"]
    spec = importlib.util.spec_from_file_location("kernel_4c4ae3c", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["kernel_4c4ae3c"] = module      # numba pickles a cached function's module by name: it must import
    spec.loader.exec_module(module)
    return module


def test_atan2_and_tanh_keep_the_4c4ae3c_bits():
    """The kernel's float64 atan2 (general and ranged) and tanh (general and finite) give the 4c4ae3c kernel's
    bits: their operations changed (ranged paths, quadrant bookkeeping by selects, 2^n from its bits), the results
    must not."""
    old = old_kernel()
    y, x = atan2_cases()
    x = np.concatenate([x, RNG.normal(0, 30, N), -y[:1000], y[:1000], np.zeros(100), -np.zeros(100)])
    y = np.concatenate([y, RNG.normal(0, 30, N), y[:1000], y[:1000], RNG.normal(0, 1, 100), RNG.normal(0, 1, 100)])
    want, got, ranged = np.empty_like(y), np.empty_like(y), np.empty_like(y)
    old.atan2_array(y, x, want)
    atan2_array(y, x, got)
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
    big = np.maximum(np.abs(x), np.abs(y))
    inside = (big >= RANGED_MIN) & (big <= RANGED_MAX)
    atan2_ranged_array(y[inside], x[inside], ranged[:inside.sum()])
    assert inside.sum() > N and np.array_equal(ranged[:inside.sum()].view(np.int64), want[inside].view(np.int64))
    t = np.concatenate([RNG.normal(0, 3, N), RNG.normal(0, 30, N), RNG.uniform(-1, 1, N), [0.625, -0.625, 19.06, 20.0]])
    want, got, finite = np.empty_like(t), np.empty_like(t), np.empty_like(t)
    old.tanh_array(t, want)
    tanh_array(t, got)
    tanh_finite_array(t, finite)
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
    assert np.array_equal(finite.view(np.int64), want.view(np.int64))


def test_finite_tanh_and_act_give_the_general_bits():
    """tanh(finite=True) leaves out the NaN case only: the same bits on every finite input; act_flat's finite path
    gives the general path's actions; mlp_finite refuses what could make a sum overflow or a reading NaN."""
    x = np.concatenate([RNG.normal(0, 3, N), RNG.normal(0, 30, N), RNG.normal(0, 0.3, N), EDGE[:-2], [0.625, 19.06]])
    general, finite = np.empty_like(x), np.empty_like(x)
    tanh_array(x, general)
    tanh_finite_array(x, finite)
    assert np.array_equal(general.view(np.int64), finite.view(np.int64))
    world = make_world("solo")
    n, e, d = world.n_rovers, world.episodes, world.obs_dim
    obs = RNG.uniform(-1, 1, d * n * e)
    obs[:n * e] = 0.0                                                   # a zero row, skipped
    genomes = RNG.uniform(-2, 2, (n, world.n_params)) * 10.0 ** RNG.integers(-3, 4, (n, 1))
    acts = [[np.empty(n * e), np.empty(n * e)] for _ in range(2)]
    every = np.tile(np.arange(d), (n, 1))
    for flag, (a0, a1) in zip((False, True), acts, strict=True):
        h = world.policy.hidden
        stages.act_flat(genomes, obs, every, e, h, np.empty((h + 2) * e), np.empty(d, np.int64), a0, a1, flag)
    assert same_bits(acts[0][0], acts[1][0]) and same_bits(acts[0][1], acts[1][1])
    r = float(world.sensor_range)
    assert checks.mlp_finite(genomes, world.task.sensor_type, r)
    typ = world.task.sensor_type
    assert not checks.mlp_finite(genomes * np.inf, typ, r) and not checks.mlp_finite(genomes, typ, 0.0)
    assert not checks.mlp_finite(genomes, world.task.sensor_type + 2.0 ** 200, r)
    assert not checks.mlp_finite(np.where(genomes > 1, np.nan, genomes), world.task.sensor_type, r)
    assert not checks.mlp_finite(np.zeros((1, 2 ** 20)), world.task.sensor_type, r)            # a sum of 2^20 terms


def test_sensing_takes_the_ranged_atan2_only_inside_its_promise():
    """sense_flat's two paths give the same bits on ordinary states; states outside checks.in_range (a coordinate
    of 1e-300, a NaN heading) take the general path."""
    world = make_world("duo")
    n, e = world.n_rovers, world.episodes
    rng = np.random.default_rng(5)
    args = (n, world.poi_xy, world.task.sensor_type, world.sensor_range)
    for trial in range(6):
        x, y = rng.uniform(-30, 30, (2, n * e))
        h = rng.uniform(-4, 4, n * e)
        x[:3] = y[:3] = 0.0                                           # rovers on the origin and on each other
        x[5], y[5] = world.poi_xy[0]                                  # a rover on a POI
        if trial == 4:
            x[7] = 1e-300
        if trial == 5:
            h[9] = math.nan
        s, c = np.empty_like(h), np.empty_like(h)
        kernel.sincos_all(h, s, c)
        got, general, ranged = (np.empty(world.obs_dim * n * e) for _ in range(3))
        stages.sense_flat(x, y, s, c, *args, got)
        stages._sense_rows(x, y, s, c, *args, general, False)
        stages._sense_rows(x, y, s, c, *args, ranged, True)
        assert checks.in_range(x, y, s, c, world.poi_xy) == (trial < 4)
        assert same_bits(got, general)
        if trial < 4:
            assert same_bits(got, ranged)
    out = np.empty((0, n, world.obs_dim))                             # no episodes: nothing to read or write
    fused.observe(np.empty((0, n, 2)), np.empty((0, n)), world.kernel, (), out)


# ---- the stages, one at a time, against the fused rollout ------------------------------------------------------

WORLDS = [("solo", {}), ("duo", {}), ("trio", {}), ("duo", {"n_rovers": 3, "hidden": 5, "episodes": 5, "steps": 7}),
          ("solo", {"n_rovers": 6, "hidden": 9, "episodes": 11, "coupling": [1, 2, 3], "value": [1.0, 2.0, 4.0]}),
          ("solo", {"n_rovers": 1, "hidden": 1, "episodes": 1, "steps": 1, "sensor_range": 12.5})]


def same_bits(a, b):
    return a.shape == b.shape and np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes()


def stepwise(world, genomes, ic):
    """T x (observe, act, step), then reward: xy (E, T+1, N, 2), heading (E, T+1, N), returns (E,)."""
    xy, heading = ic[0].copy(), ic[1].copy()
    e, n = heading.shape
    obs, actions = np.empty((e, n, world.obs_dim)), np.empty((e, n, 2))
    traj_xy, traj_heading = [xy.copy()], [heading.copy()]
    for _ in range(world.steps):
        fused.observe(xy, heading, world.kernel, (), obs)
        kernel.act(genomes, obs, world.policy.hidden, actions)
        fused.step(xy, heading, actions, world.kernel, ())
        traj_xy.append(xy.copy())
        traj_heading.append(heading.copy())
    returns = np.empty(e)
    kernel.reward(xy, world.poi_xy, world.task.coupling, world.task.value, world.obs_radius, returns)
    return np.stack(traj_xy, axis=1), np.stack(traj_heading, axis=1), returns


@pytest.mark.parametrize("setup,overrides", WORLDS)
def test_stages_one_at_a_time_give_the_rollout_bit_for_bit(setup, overrides):
    world = make_world(setup, **overrides)
    rng = np.random.default_rng(11)
    for t in range(4):
        ic = world.initial_conditions(seed=t)
        if t == 3:                                                  # far from the start boxes, large headings
            ic = (ic[0] + rng.uniform(-40, 40, ic[0].shape), ic[1] + rng.uniform(-1e3, 1e3, ic[1].shape))
        genomes = rng.uniform(-2, 2, (world.n_rovers, world.n_params)) * (1 + 4 * t)
        roll = world.rollout(genomes, ic)
        xy, heading, returns = stepwise(world, genomes, ic)
        assert same_bits(xy, roll.xy) and same_bits(heading, roll.heading) and same_bits(returns, roll.returns)


def test_sense_and_act_give_the_fused_loops_numbers():
    """The batch-first adapters read and write the flat layout of the fused loops (one step, checked by hand)."""
    world = make_world("duo", n_rovers=3, hidden=4)
    xy, heading, _ = world.initial_conditions(seed=2, n=5)
    xy = xy + np.random.default_rng(0).uniform(-20, 20, xy.shape)
    e, n, d = 5, 3, world.obs_dim
    obs = np.empty((e, n, d))
    fused.observe(xy, heading, world.kernel, (), obs)
    x, y, h = (np.ascontiguousarray(a.T).ravel() for a in (xy[..., 0], xy[..., 1], heading))   # q = i*E + e
    s, c, flat = np.empty(n * e), np.empty(n * e), np.empty(d * n * e)
    kernel.sincos_all(h, s, c)
    stages.sense_flat(x, y, s, c, n, world.poi_xy, world.task.sensor_type, world.sensor_range, flat)
    assert same_bits(obs, flat.reshape(d, n, e).transpose(2, 1, 0))
    np.testing.assert_allclose(obs, world.observe(xy, heading), rtol=0, atol=1e-14)   # libm twin: a few ulp
    genomes = np.random.default_rng(1).uniform(-2, 2, (n, world.n_params))
    actions = np.empty((e, n, 2))
    kernel.act(genomes, obs, world.policy.hidden, actions)
    a0, a1 = np.empty(n * e), np.empty(n * e)
    cand = checks.input_rows(n, world.task.sensor_type)           # as the rollout: no structural zero rows
    h = world.policy.hidden
    stages.act_flat(genomes, flat, cand, e, h, np.empty((h + 2) * e), np.empty(d, np.int64), a0, a1)
    assert same_bits(actions, np.stack([a0.reshape(n, e).T, a1.reshape(n, e).T], axis=-1))
    assert (cand == -1).sum() == n * (2 + (world.task.sensor_type == 0).sum())   # own slot and type-0 rows left out


@pytest.mark.parametrize(("episodes", "hidden"), [(16, 16), (8, 16), (20, 6), (3, 5), (24, 4), (1, 1)])
def test_register_tiles_sum_as_plain_loops(episodes, hidden):
    """The register tiles (simd.hidden_tile: 4 units x 8 episodes; simd.output_tile: 2 outputs x 8 episodes) and
    the loops for what they leave (other unit and episode counts) give the plain loops' numbers bit for bit, zero
    input rows skipped or not."""
    rng = np.random.default_rng(episodes * 100 + hidden)
    n, d = 3, 14
    obs = rng.uniform(-1, 1, (episodes, n, d))
    obs[:, :, [2, 7]] = 0.0                                    # rows zero in every episode: the kernel skips them
    obs[: episodes // 2, 1, 5] = 0.0                           # zero in some episodes only: summed
    genomes = rng.uniform(-2, 2, (n, (d + 3) * hidden + 2))
    got, want = np.empty((episodes, n, 2)), np.empty((episodes, n, 2))
    kernel.act(genomes, obs, hidden, got)
    act_plain(genomes, obs, hidden, want)
    assert same_bits(got, want)
    strided = np.repeat(genomes, 2, axis=1)[:, ::2]             # the same genomes, not contiguous: no tiles
    kernel.act(strided, obs, hidden, got)
    assert same_bits(got, want)


def test_poi_test_has_one_home():
    """observers, poi_of and reward agree with a brute-force count of distances <= radius, ties included."""
    world = make_world("duo")
    rng = np.random.default_rng(3)
    xy = world.poi_xy[rng.integers(0, 10, (200, 4))] + rng.normal(0, 1.5, (200, 4, 2))
    xy[:20, 0] = world.poi_xy[rng.integers(0, 10, 20)] + [world.obs_radius, 0.0]     # exactly on the radius
    dist = np.sqrt(((world.poi_xy[None, None] - xy[:, :, None]) ** 2).sum(-1))      # (E, N, P)
    inside = dist <= world.obs_radius
    count = np.zeros((200, 10), dtype=np.int8)
    kernel.observers(xy, world.poi_xy, world.obs_radius, count)
    np.testing.assert_array_equal(count, inside.sum(axis=1))
    first = np.where(inside.any(-1), inside.argmax(-1), -1)
    assert all(kernel.poi_of(*xy[e, i], world.poi_xy, world.obs_radius) == first[e, i]
               for e in range(200) for i in range(4))
    returns, paid = np.empty(200), np.empty(200)
    kernel.reward(xy, world.poi_xy, world.task.coupling, world.task.value, world.obs_radius, returns)
    kernel.payout(count, world.task.coupling, world.task.value, paid)
    np.testing.assert_array_equal(returns, paid)
    np.testing.assert_array_equal(returns, np.where(count >= world.task.coupling, world.task.value, 0).sum(-1))
    np.testing.assert_array_equal(returns, world.team_return(xy))


@pytest.mark.parametrize("fn", [kernel.act, kernel.observers, kernel.payout,
                                kernel.reward, rules.within, rules.poi_of, checks.input_rows],
                         ids=lambda f: f.__name__)
def test_docstring_examples_run(fn):
    test = doctest.DocTestParser().get_doctest(fn.__doc__, {fn.__name__: fn}, fn.__name__, None, 0)
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    runner.run(test)
    assert test.examples and runner.failures == 0


# ---- env.dtype=float32 ------------------------------------------------------------------------------------------

def ulps32(got, want):
    """Error of float32 got in float32 ulps of the float64 value want."""
    want32 = np.abs(want).astype(np.float32)
    return np.abs(got.astype(np.float64) - want) / np.spacing(np.maximum(want32, np.float32(1e-30))).astype(float)


def test_float32_functions_are_float32_and_near_the_true_value():
    from numba import njit, types

    f = np.float32
    x = np.concatenate([RNG.uniform(-12, 12, N), RNG.normal(0, 1e-3, N // 10), [0.0, 7.9, -9.0, 20.0]]).astype(f)
    got = np.empty_like(x)
    tanh_array(x, got)
    assert ulps32(got, np.tanh(x.astype(float))).max() <= 5                      # measured 4.4
    y, z = RNG.uniform(-40, 40, N).astype(f), RNG.uniform(-40, 40, N).astype(f)
    got = np.empty_like(y)
    atan2_array(y, z, got)
    assert ulps32(got, np.arctan2(y.astype(float), z.astype(float))).max() <= 3    # measured 2.1
    a = RNG.uniform(-40, 40, N).astype(f)
    s, c = np.empty_like(a), np.empty_like(a)
    kernel.sincos_all(a, s, c)
    assert np.abs(s - np.sin(a.astype(float))).max() < 4e-7 and np.abs(c - np.cos(a.astype(float))).max() < 4e-7
    wrapped = (njit(lambda v: kernel.tanh(v)), njit(lambda v: kernel.atan2(v, v)), njit(lambda v: kernel.sincos(v)))
    for fn in wrapped:                                                             # no float64 inside
        fn(f(0.5))
        ret = fn.nopython_signatures[0].return_type
        assert ret in (types.float32, types.UniTuple(types.float32, 2)), ret


def test_float32_rollouts_are_close_to_float64():
    w64, w32 = make_world("duo"), make_world("duo", dtype="float32")
    rng = np.random.default_rng(3)
    ic = w64.run_ic(3)
    for t in range(5):
        genomes = rng.normal(0, 0.3, (4, w64.n_params))
        r64, r32 = w64.rollout(genomes, ic), w32.rollout(genomes, ic)
        assert r32.xy.dtype == r32.returns.dtype == np.float64
        assert 0 < np.abs(r32.xy - r64.xy).max() < 1e-3, t                     # close, not equal
        assert np.array_equal(r32.returns, w32.returns(genomes, ic))

