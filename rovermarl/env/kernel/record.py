"""The world as the kernel reads it: :class:`KernelWorld`, one record passed whole to every compiled function.

Its own module, so that every compiled copy of :mod:`~rovermarl.env.kernel.fused` (:mod:`~rovermarl.env.kernel.compose`)
types the record as the same class: numba's cache index pickles a function's argument types, and a class of a
generated module would be looked up under that module's name in every later process.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rovermarl.env.kernel import checks
from rovermarl.env.kernel.rules import REWARDS, SPEEDS


class KernelWorld(NamedTuple):
    """The world as the kernel reads it, owned by :class:`~rovermarl.env.World` (``World.kernel``) and passed whole.

    poi_xy (P, 2) and poi_type (P,) (the sensors' third number) in the kernel's precision (``env.dtype``); coupling
    (P,) int64; value (P,) float64; ``steps`` T, ``hidden`` H and ``obs_dim`` D; sensor_range, obs_radius, v_max and
    w_max (radians) in the kernel's precision; ``speed_mode`` and ``reward_mode`` the indices of ``env.speed`` and
    ``env.reward`` in :mod:`~rovermarl.env.kernel.rules`; ``layout`` (E, K) float64, what the initial conditions
    draw per episode besides the rovers' starts (K = 0 for the paper's world; ``World.kernel_for`` sets it per call);
    ``extra``, a tuple of a world plug-in's own arrays and numbers (``World.kernel_extra``; empty here); ``rows``
    (N, D) int64, each rover's input rows that may be nonzero, increasing, then -1 (:func:`input_rows`, from the
    observation's declared blocks); ``state_dims`` (S,) int64, the width of each declared state array
    (``World.state``; empty for a world without state).
    """

    poi_xy: np.ndarray
    poi_type: np.ndarray
    coupling: np.ndarray
    value: np.ndarray
    steps: int
    hidden: int
    obs_dim: int
    sensor_range: float
    obs_radius: float
    v_max: float
    w_max: float
    speed_mode: int
    reward_mode: int
    layout: np.ndarray
    extra: tuple
    rows: np.ndarray
    state_dims: np.ndarray


def build(params, task, blocks: list, layout_dim: int, extra: tuple, state_dims: np.ndarray) -> KernelWorld:
    """The record of a world (``World.kernel``) from its parts: ``params`` (its :class:`~rovermarl.env.params.Params`
    fields), ``task`` (:class:`~rovermarl.env.task.Task`), the observation's ``blocks`` (``World.obs_blocks``), the
    layout's width K, the plug-in's ``extra`` (``World.kernel_extra``) and its state's widths; in the kernel's
    precision (``env.dtype``), with an empty layout (``World.kernel_for`` sets the initial conditions')."""
    f = np.dtype(params.dtype).type
    return KernelWorld(
        task.poi_xy.astype(f), task.sensor_type.astype(f), task.coupling.copy(), task.value.copy(), params.steps,
        params.policy.hidden, int(sum(low.size for _, low, _ in blocks)), f(params.sensor_range), f(params.obs_radius),
        f(params.v_max), f(math.radians(params.w_max_deg)), SPEEDS.index(params.speed), REWARDS.index(params.reward),
        np.empty((0, layout_dim)), extra, input_rows(blocks, params.n_rovers, task.sensor_type), state_dims)


def input_rows(blocks: list, n: int, sensor_type: np.ndarray) -> np.ndarray:
    """(N, D) int64: each rover's observation rows that may be nonzero, increasing, then -1 (what the MLP reads,
    ``KernelWorld.rows``). Of the paper's blocks (first, ``poi`` and ``rover``) those ``checks.input_rows`` keeps,
    then every row of a plug-in's own blocks; every row if its first blocks are not the paper's (reading a row of
    zeros costs time, never a result).

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
