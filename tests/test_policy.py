"""Genome layout, and the compiled policies (the kernel's act stage, a libm twin) against policy.forward."""

import numpy as np
import pytest
from kernel_helpers import act_libm

from rovermarl import make_world, policy
from rovermarl.env import kernel


def test_layout_offsets():
    g = np.arange(658, dtype=np.float64)
    w1, b1, w2, b2 = policy.unflatten(g, 38, 16)
    assert w1.shape == (38, 16) and b1.shape == (16,) and w2.shape == (16, 2) and b2.shape == (2,)
    assert w1[0, 0] == 0 and w1[0, 1] == 1 and w1[1, 0] == 16      # input-major rows
    assert w1[37, 15] == 607 and b1[0] == 608 and b1[15] == 623
    assert w2[0, 0] == 624 and w2[0, 1] == 625 and w2[1, 0] == 626 and w2[15, 1] == 655
    np.testing.assert_array_equal(b2, [656, 657])
    np.testing.assert_array_equal(policy.flatten(w1, b1, w2, b2), g)
    assert policy.n_params(38, 16) == 658


def test_libm_policy_matches_numpy_reference():
    rng = np.random.default_rng(0)
    buf = np.empty(16)
    for _ in range(20):
        g = rng.uniform(-2, 2, 658)
        obs = rng.uniform(-1, 1, 38)
        np.testing.assert_allclose(act_libm(g, obs, 16, buf), policy.forward(g, obs, 16), rtol=1e-12, atol=1e-14)


def test_act_stage_matches_numpy_reference():
    """The kernel's act stage over a batch (E, N, D), zero inputs included, equals the MLP to rounding."""
    rng = np.random.default_rng(2)
    genomes = rng.uniform(-2, 2, (4, 658))
    obs = rng.uniform(-1, 1, (7, 4, 38))
    obs[:, :, 30:32] = 0.0                                       # a row that is zero in every episode is skipped
    obs[2, 1] = 0.0
    out = np.empty((7, 4, 2))
    kernel.act(genomes, obs, 16, out)
    want = np.array([[policy.forward(genomes[i], obs[e, i], 16) for i in range(4)] for e in range(7)])
    np.testing.assert_allclose(out, want, rtol=1e-12, atol=1e-14)


def test_single_weight_routes_one_input_to_one_output():
    """W1[i, h] connects input i to hidden h; W2[h, o] connects hidden h to output o."""
    world = make_world("solo")
    g = np.zeros(658)
    w1, b1, w2, b2 = policy.unflatten(g, 38, 16)  # views into g
    w1[4, 7] = 2.0                                   # input 4 = bearing of POI 1
    w2[7, 1] = 1.5                                   # hidden 7 -> turn
    obs = np.zeros(38)
    obs[4] = 0.3
    a0, a1 = act_libm(g, obs, 16, np.empty(16))
    assert a0 == 0.0
    assert a1 == pytest.approx(np.tanh(1.5 * np.tanh(0.6)), rel=1e-14)
    assert world.n_params == g.size
