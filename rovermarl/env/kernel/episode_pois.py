"""The paper's sensing and reward with POIs that differ per episode (numba), for world plug-ins whose POIs an
episode's layout places (``examples/random_pois``) or its state moves (``examples/moving_pois``). ``pois`` (E, 2P):
episode e's POI j at ``(pois[e, 2j], pois[e, 2j + 1])``; pair ``q = i*E + e`` as in the kernel's flat layout.
"""

from __future__ import annotations

import math

import numpy as np

from rovermarl.env.kernel.math import FAST, like
from rovermarl.env.kernel.reward import payout
from rovermarl.env.kernel.rules import bearing, reading, within
from rovermarl.env.kernel.stages import sense_rovers
from rovermarl.jit import njit


@njit(inline="always", **FAST)
def sense_at(x, y, sin_h, cos_h, n, pois, poi_type, sensor_range, obs):
    """The paper's sensors (``stages.sense_flat``'s rows, D = 3P + 2N) with each episode's POIs ``pois`` (E, 2P);
    returns False (not the ranged bearings: the MLP keeps its general tanh)."""
    ne = x.shape[0]
    ep = ne // n
    inv_pi = like(sensor_range, 1.0 / math.pi)
    for j in range(poi_type.shape[0]):
        o = 3 * j * ne
        for q in range(ne):
            e = q % ep
            dx = like(x[q], pois[e, 2 * j]) - x[q]
            dy = like(x[q], pois[e, 2 * j + 1]) - y[q]
            d = math.sqrt(dx * dx + dy * dy)
            b = bearing(dx, dy, cos_h[q], sin_h[q], False)
            obs[o + q], obs[o + ne + q], obs[o + 2 * ne + q] = reading(
                d, sensor_range, d / sensor_range, b * inv_pi, poi_type[j])
    sense_rovers(x, y, sin_h, cos_h, n, 3 * poi_type.shape[0], sensor_range, obs)
    return False


@njit(inline="always", cache=True)
def reward_at(xy, pois, coupling, value, obs_radius, returns):
    """The paper's reward rule (``within``, ``payout``) with each episode's POIs ``pois`` (E, 2P): xy (E, N, 2)
    float64 -> returns (E,)."""
    count = np.zeros((xy.shape[0], coupling.shape[0]), np.int64)
    for e in range(xy.shape[0]):
        for j in range(coupling.shape[0]):
            for i in range(xy.shape[1]):
                count[e, j] += within(pois[e, 2 * j], pois[e, 2 * j + 1], xy[e, i, 0], xy[e, i, 1], obs_radius)
    payout(count, coupling, value, returns)


@njit(inline="always", cache=True)
def final_only(w):
    """``stepwise`` of a reward of the final positions only."""
    return False


@njit(inline="always", cache=True)
def no_acc(w, n_ep):
    """``score_start`` of a reward of the final positions only: nothing to carry."""
    return (np.empty(0),)


@njit(inline="always", cache=True)
def no_step(w, x, y, xy, acc, s):
    """``score_step`` of a reward of the final positions only."""
