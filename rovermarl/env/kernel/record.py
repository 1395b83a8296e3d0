"""The world as the kernel reads it: :class:`KernelWorld`, one record passed whole to every compiled function.

Its own module, so that every compiled copy of :mod:`~rovermarl.env.kernel.fused` types the record as the same class:
numba's cache index pickles a function's argument types, and a class of a generated module would be looked up under
that module's name in every later process.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rovermarl.env.kernel import checks
from rovermarl.env.kernel.rules import REWARDS, SPEEDS


class KernelWorld(NamedTuple):
    """The world as the kernel reads it, owned by :class:`~rovermarl.env.World` (``World.kernel``) and passed whole.
    Floats are in the kernel's precision (``env.dtype``) unless said."""

    poi_xy: np.ndarray          # (P, 2)
    poi_type: np.ndarray        # (P,), the sensors' third number
    coupling: np.ndarray        # (P,) int64
    value: np.ndarray           # (P,) float64
    steps: int                  # T
    hidden: int                 # H
    obs_dim: int                # D
    sensor_range: float
    obs_radius: float
    v_max: float
    w_max: float                # radians
    speed_mode: int             # the index of env.speed in rules.SPEEDS
    reward_mode: int            # the index of env.reward in rules.REWARDS
    layout: np.ndarray          # (E, K) float64, drawn per episode besides the starts (World.kernel_for; K = 0 here)
    extra: tuple                # a world plug-in's own arrays and numbers (World.kernel_extra; empty here)
    rows: np.ndarray            # (N, D) int64: input rows that may be nonzero, increasing, then -1 (input_rows)
    state_dims: np.ndarray      # (S,) int64: each declared state array's width (World.state; empty without state)


def build(params, task, blocks: list, layout_dim: int, extra: tuple, state_dims: np.ndarray) -> KernelWorld:
    """The record of a world (``World.kernel``) from its :class:`~rovermarl.env.params.Params`, its
    :class:`~rovermarl.env.task.Task` and ``World.obs_blocks``, ``layout_dim`` (K), ``kernel_extra`` and its state's
    widths, with an empty layout (``World.kernel_for`` sets the initial conditions')."""
    f = np.dtype(params.dtype).type
    rows = input_rows(blocks, params.n_rovers, task.sensor_type)
    return KernelWorld(
        task.poi_xy.astype(f), task.sensor_type.astype(f), task.coupling.copy(), task.value.copy(), params.steps,
        params.policy.hidden, rows.shape[1], f(params.sensor_range), f(params.obs_radius), f(params.v_max),
        f(math.radians(params.w_max_deg)), SPEEDS.index(params.speed), REWARDS.index(params.reward),
        np.empty((0, layout_dim)), extra, rows, state_dims)


def input_rows(blocks: list, n: int, sensor_type: np.ndarray) -> np.ndarray:
    """``KernelWorld.rows`` (N, D) int64: of the paper's blocks (first, ``poi`` and ``rover``) the rows
    ``checks.input_rows`` keeps, then every row of a plug-in's own blocks; every row if its first blocks are not the
    paper's (reading a row of zeros costs time, never a result).

    >>> from rovermarl.env import make_world
    >>> make_world("solo").kernel.rows[0, :4].tolist()        # POI 0's type row (type 0) is left out
    [0, 1, 3, 4]
    """
    d = int(sum(low.size for _, low, _ in blocks))
    paper = [("poi", 3 * sensor_type.size), ("rover", 2 * n)]
    out = np.full((n, d), -1, dtype=np.int64)
    if [(name, low.size) for name, low, _ in blocks[:2]] != paper:
        out[:] = np.arange(d)
        return out
    base, k0 = checks.input_rows(n, sensor_type), sum(size for _, size in paper)
    for i in range(n):
        mine = np.concatenate([base[i][base[i] >= 0], np.arange(k0, d)])
        out[i, :mine.size] = mine
    return out
