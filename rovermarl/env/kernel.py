"""Compiled rollout kernel (numba). All functions work on one episode or a batch of episodes.

Shapes: N rovers, P POIs, D = 3P + 2N observation size, H hidden units, E episodes, T steps.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi


@njit(cache=True, inline="always")
def _wrap(a):
    """Angle wrapped to [-pi, pi)."""
    r = a - TWO_PI * math.floor((a + math.pi) / TWO_PI)
    if r >= math.pi:  # rounding in the floor can land one ulp outside
        r -= TWO_PI
    elif r < -math.pi:
        r += TWO_PI
    return r


@njit(cache=True)
def sense(xy, heading, poi_xy, poi_type, sensor_range, out):
    """Observations of one episode's rovers.

    xy (N, 2), heading (N,), poi_xy (P, 2), poi_type (P,) = coupling - 1 -> out (N, 3P + 2N).
    POI j fills ``[d / range, bearing / pi, type]`` at 3j; rover m fills ``[d / range, bearing / pi]``
    at 3P + 2m (own slot ``[0, 0]``). Targets beyond range read ``[1, 0, 0]`` / ``[1, 0]``.
    """
    n = xy.shape[0]
    p = poi_xy.shape[0]
    for i in range(n):
        x = xy[i, 0]
        y = xy[i, 1]
        h = heading[i]
        for j in range(p):
            dx = poi_xy[j, 0] - x
            dy = poi_xy[j, 1] - y
            d = math.sqrt(dx * dx + dy * dy)
            o = 3 * j
            if d > sensor_range:
                out[i, o] = 1.0
                out[i, o + 1] = 0.0
                out[i, o + 2] = 0.0
            else:
                out[i, o] = d / sensor_range
                out[i, o + 1] = _wrap(math.atan2(dy, dx) - h) / math.pi
                out[i, o + 2] = poi_type[j]
        for m in range(n):
            o = 3 * p + 2 * m
            dx = xy[m, 0] - x
            dy = xy[m, 1] - y
            d = math.sqrt(dx * dx + dy * dy)
            if m == i:
                out[i, o] = 0.0
                out[i, o + 1] = 0.0
            elif d > sensor_range:
                out[i, o] = 1.0
                out[i, o + 1] = 0.0
            else:
                out[i, o] = d / sensor_range
                out[i, o + 1] = _wrap(math.atan2(dy, dx) - h) / math.pi


@njit(cache=True)
def team_return(xy, poi_xy, coupling, value, obs_radius):
    """Return of one episode from final positions xy (N, 2): sum of values of satisfied POIs."""
    total = 0.0
    for j in range(poi_xy.shape[0]):
        count = 0
        for i in range(xy.shape[0]):
            dx = poi_xy[j, 0] - xy[i, 0]
            dy = poi_xy[j, 1] - xy[i, 1]
            if math.sqrt(dx * dx + dy * dy) <= obs_radius:
                count += 1
        if count >= coupling[j]:
            total += value[j]
    return total


@njit(cache=True)
def act(genome, obs, hidden, h_buf):
    """MLP forward for one rover: genome (P,), obs (D,) -> (a0, a1) in [-1, 1]; h_buf (H,) scratch."""
    d = obs.shape[0]
    o_b1 = d * hidden
    o_w2 = o_b1 + hidden
    o_b2 = o_w2 + 2 * hidden
    for u in range(hidden):
        h_buf[u] = genome[o_b1 + u]
    for i in range(d):
        v = obs[i]
        row = i * hidden
        for u in range(hidden):
            h_buf[u] += v * genome[row + u]
    z0 = genome[o_b2]
    z1 = genome[o_b2 + 1]
    for u in range(hidden):
        t = math.tanh(h_buf[u])
        z0 += t * genome[o_w2 + 2 * u]
        z1 += t * genome[o_w2 + 2 * u + 1]
    return math.tanh(z0), math.tanh(z1)


@njit(cache=True)
def rollout(genomes, xy0, heading0, poi_xy, poi_type, coupling, value, steps, hidden,
            sensor_range, obs_radius, v_max, w_max, returns, traj_xy, traj_heading, final_xy):
    """Run E episodes of T steps for one team.

    genomes (N, P) one row per rover; xy0 (E, N, 2), heading0 (E, N) -> returns (E,) written in place.
    If ``traj_xy`` has shape (E, T+1, N, 2) (and ``traj_heading`` (E, T+1, N)) the states are
    recorded there; pass arrays with a zero-sized first axis to skip recording. Likewise the final
    positions go to ``final_xy`` (E, N, 2) unless its first axis is zero-sized.
    Each step: all rovers sense, all act, then each turns by ``a1 * w_max`` and moves
    ``(a0 + 1) / 2 * v_max`` along its new heading.
    """
    n_ep, n = heading0.shape
    record = traj_xy.shape[0] == n_ep
    keep_final = final_xy.shape[0] == n_ep
    d = 3 * poi_xy.shape[0] + 2 * n
    obs = np.empty((n, d))
    h_buf = np.empty(hidden)
    speed = np.empty(n)
    turn = np.empty(n)
    xy = np.empty((n, 2))
    heading = np.empty(n)
    for e in range(n_ep):
        for i in range(n):
            xy[i, 0] = xy0[e, i, 0]
            xy[i, 1] = xy0[e, i, 1]
            heading[i] = heading0[e, i]
        if record:
            traj_xy[e, 0] = xy
            traj_heading[e, 0] = heading
        for t in range(steps):
            sense(xy, heading, poi_xy, poi_type, sensor_range, obs)
            for i in range(n):
                a0, a1 = act(genomes[i], obs[i], hidden, h_buf)
                speed[i] = (a0 + 1.0) * 0.5 * v_max
                turn[i] = a1 * w_max
            for i in range(n):
                heading[i] += turn[i]
                xy[i, 0] += speed[i] * math.cos(heading[i])
                xy[i, 1] += speed[i] * math.sin(heading[i])
            if record:
                traj_xy[e, t + 1] = xy
                traj_heading[e, t + 1] = heading
        if keep_final:
            final_xy[e] = xy
        returns[e] = team_return(xy, poi_xy, coupling, value, obs_radius)


@njit(cache=True)
def sense_batch(xy, heading, poi_xy, poi_type, sensor_range, out):
    """xy (B, N, 2), heading (B, N) -> out (B, N, D)."""
    for b in range(xy.shape[0]):
        sense(xy[b], heading[b], poi_xy, poi_type, sensor_range, out[b])


@njit(cache=True)
def team_return_batch(xy, poi_xy, coupling, value, obs_radius, out):
    """xy (B, N, 2) -> out (B,)."""
    for b in range(xy.shape[0]):
        out[b] = team_return(xy[b], poi_xy, coupling, value, obs_radius)
