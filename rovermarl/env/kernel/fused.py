"""The fused team rollout (numba): the hot path of every evaluation, built from the stage loops of
:mod:`rovermarl.env.kernel.stages` on their flat layout, with all buffers allocated once per call."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rovermarl.env.kernel.checks import input_rows, mlp_finite
from rovermarl.env.kernel.math import FAST, sincos_all
from rovermarl.env.kernel.reward import fold, reward, settle, start
from rovermarl.env.kernel.rules import FINAL
from rovermarl.env.kernel.stages import act_flat, from_flat, move_flat, sense_flat, to_flat
from rovermarl.jit import njit


class KernelWorld(NamedTuple):
    """The world as the kernel reads it, owned by :class:`~rovermarl.env.World` (``World.kernel``) and passed whole.

    poi_xy (P, 2) and poi_type (P,) (the sensors' third number) in the kernel's precision (``env.dtype``); coupling
    (P,) int64; value (P,) float64; ``steps`` T and ``hidden`` H; sensor_range, obs_radius, v_max and w_max (radians)
    in the kernel's precision; ``speed_mode`` and ``reward_mode`` the indices of ``env.speed`` and ``env.reward`` in
    :mod:`~rovermarl.env.kernel.rules`.
    """

    poi_xy: np.ndarray
    poi_type: np.ndarray
    coupling: np.ndarray
    value: np.ndarray
    steps: int
    hidden: int
    sensor_range: float
    obs_radius: float
    v_max: float
    w_max: float
    speed_mode: int
    reward_mode: int


@njit(**FAST)
def rollout(genomes, xy0, heading0, w, returns, traj_xy, traj_heading, final_xy):
    """Run E episodes of T steps for one team in the world ``w`` (a :class:`KernelWorld`); the per-episode team
    returns go to ``returns`` (E,).

    genomes (N, G) one row per rover; xy0 (E, N, 2), heading0 (E, N). The dynamics run in the precision of
    ``genomes``, ``xy0``, ``heading0`` and ``w``'s floats (all float64, or all float32 under ``env.dtype=float32``);
    returns and trajectories are float64.
    If ``traj_xy`` has shape (E, T+1, N, 2) (and ``traj_heading`` (E, T+1, N)) the states are recorded there; pass
    arrays with a zero-sized first axis to skip recording. Likewise the final positions go to ``final_xy`` (E, N, 2)
    unless its first axis is zero-sized.
    Each step: all rovers sense, all act, then each turns and moves (``sense_flat``, ``act_flat``, ``move_flat``).
    After the last step, :func:`~rovermarl.env.kernel.reward.reward` scores the final positions (``env.reward=final``);
    a per-step reading folds the positions after every step instead (``fold``, then ``settle``).
    """
    _rollout(genomes, xy0, heading0, w.poi_xy, w.poi_type, w.coupling, w.value, w.steps, w.hidden, w.sensor_range,
             w.obs_radius, w.v_max, w.w_max, w.speed_mode, w.reward_mode, returns, traj_xy, traj_heading, final_xy)


@njit(**FAST)
def _rollout(genomes, xy0, heading0, poi_xy, poi_type, coupling, value, steps, hidden, sensor_range, obs_radius,
             v_max, w_max, speed_mode, reward_mode, returns, traj_xy, traj_heading, final_xy):
    """:func:`rollout` on the record's fields one by one: compiled as its own function, its arguments are plain
    arrays and numbers (measured: the record unpacked inside the loop's function cost 4-8% of the kernel)."""
    n_ep, n = heading0.shape
    ne = n * n_ep
    record = traj_xy.shape[0] == n_ep
    d = 3 * poi_xy.shape[0] + 2 * n
    state = np.empty((7, ne), dtype=xy0.dtype)         # the world's state in the kernel's precision (env.dtype)
    x, y, heading, sin_h, cos_h, a0, a1 = state[0], state[1], state[2], state[3], state[4], state[5], state[6]
    obs = np.empty(d * ne, dtype=xy0.dtype)
    hid = np.empty((hidden + 2) * n_ep, dtype=xy0.dtype)
    rows, cand = np.empty(d, dtype=np.int64), input_rows(n, poi_type)
    to_flat(xy0[:, :, 0], x)
    to_flat(xy0[:, :, 1], y)
    to_flat(heading0, heading)
    if record:
        traj_xy[:, 0] = xy0
        traj_heading[:, 0] = heading0
    sincos_all(heading, sin_h, cos_h)
    finite = mlp_finite(genomes, poi_type, sensor_range)   # with each step's in_range: the MLP's sums are finite
    xy = np.empty((n_ep, n, 2))                         # positions for the reward: float64 always
    per_step = reward_mode != FINAL
    p = poi_xy.shape[0] if per_step else 0
    count, step, peak, acc = start(reward_mode, n_ep, p)
    for t in range(steps):
        ranged = sense_flat(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs)
        act_flat(genomes, obs, cand, n_ep, hidden, hid, rows, a0, a1, finite and ranged)
        move_flat(x, y, heading, sin_h, cos_h, a0, a1, v_max, w_max, speed_mode)
        if record:
            from_flat(x, traj_xy[:, t + 1, :, 0])
            from_flat(y, traj_xy[:, t + 1, :, 1])
            from_flat(heading, traj_heading[:, t + 1])
        if per_step:                                  # env.reward read at every step (SPEC section 8)
            from_flat(x, xy[:, :, 0])
            from_flat(y, xy[:, :, 1])
            fold(reward_mode, xy, poi_xy, coupling, value, obs_radius, count, step, peak, acc)
    from_flat(x, xy[:, :, 0])
    from_flat(y, xy[:, :, 1])
    if final_xy.shape[0] == n_ep:
        final_xy[:] = xy
    if per_step:
        settle(reward_mode, steps, coupling, value, peak, acc, returns)
    else:                                             # SPEC section 1: the positions after the last step
        reward(xy, poi_xy, coupling, value, obs_radius, returns)
