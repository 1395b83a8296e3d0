"""The fast kernel's own elementary functions against libm, and its rollouts against the plain numpy rollout."""

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from rovermarl import make_world
from rovermarl.env import kernel

_SPEC = importlib.util.spec_from_file_location(
    "numpy_rollout", Path(__file__).resolve().parents[1] / "benchmarks" / "numpy_rollout.py")
numpy_rollout = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(numpy_rollout)

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
    kernel.atan2_array(y, x, got)
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
    kernel.tanh_array(x, got)
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
        kernel._sincos_all(angles, s, c)
        assert ulps(s, libm(math.sin, angles)).max() <= 2
        assert ulps(c, libm(math.cos, angles)).max() <= 2
    far = np.array([1e6, -3e7, 1e300, 123456.789])                          # beyond SINCOS_MAX: libm
    s, c = np.empty(4), np.empty(4)
    kernel._sincos_all(far, s, c)
    np.testing.assert_array_equal(s, np.sin(far))
    np.testing.assert_array_equal(c, np.cos(far))


def test_bearing_wraps_to_minus_pi_and_handles_zero_offset():
    h = 0.3
    c, s = math.cos(h), math.sin(h)
    b = kernel._bearing(-math.cos(h), -math.sin(h), c, s)        # straight behind: pi, read as -pi
    assert -math.pi <= b < -math.pi + 1e-15
    assert kernel._bearing(0.0, 0.0, c, s) == pytest.approx(-h, abs=1e-15)   # atan2(0, 0) - h


WORLDS = [("solo", {}), ("duo", {}), ("duo", {"n_rovers": 3, "hidden": 5, "episodes": 5, "steps": 7}),
          ("solo", {"n_rovers": 6, "hidden": 9, "episodes": 11, "coupling": [1, 2, 3], "value": [1.0, 2.0, 4.0]}),
          ("solo", {"n_rovers": 1, "hidden": 1, "episodes": 1, "steps": 1, "sensor_range": 12.5})]


@pytest.mark.parametrize("setup,overrides", WORLDS)
def test_kernel_matches_numpy_rollout(setup, overrides):
    """Returns equal, trajectories within 1e-8 after all steps (rounding differences grow ~1e6-fold in 15 steps;
    the old scalar libm kernel and the numpy rollout also differ by up to ~4e-10)."""
    world = make_world(setup, **overrides)
    ic = world.initial_conditions(seed=3)
    rng = np.random.default_rng(7)
    for _ in range(6):
        genomes = rng.uniform(-2, 2, (world.n_rovers, world.n_params))
        roll = world.rollout(genomes, ic)
        xy, heading, returns = numpy_rollout.rollout(world, genomes, ic, record=True)
        np.testing.assert_array_equal(roll.returns, returns)
        np.testing.assert_allclose(roll.xy, xy, rtol=0, atol=1e-8)
        np.testing.assert_allclose(roll.heading, heading, rtol=0, atol=1e-8)
        final = np.empty_like(ic[0])
        np.testing.assert_array_equal(world.returns(genomes, ic, final), returns)
        np.testing.assert_array_equal(final, roll.xy[:, -1])


def test_numpy_rollout_observe_matches_world_observe():
    world = make_world("duo")
    rng = np.random.default_rng(1)
    xy, heading = rng.uniform(-35, 35, (9, 4, 2)), rng.uniform(-20, 20, (9, 4))
    np.testing.assert_allclose(numpy_rollout.observe(world, xy, heading), world.observe(xy, heading),
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(numpy_rollout.team_return(world, xy), world.team_return(xy))
