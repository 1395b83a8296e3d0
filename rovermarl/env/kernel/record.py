"""The world as the kernel reads it: :class:`KernelWorld`, one record passed whole to every compiled function.

Its own module, so that every compiled copy of :mod:`~rovermarl.env.kernel.fused` (:mod:`~rovermarl.env.kernel.compose`)
types the record as the same class: numba's cache index pickles a function's argument types, and a class of a
generated module would be looked up under that module's name in every later process.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rovermarl.env.kernel.rules import REWARDS, SPEEDS


class KernelWorld(NamedTuple):
    """The world as the kernel reads it, owned by :class:`~rovermarl.env.World` (``World.kernel``) and passed whole.

    poi_xy (P, 2) and poi_type (P,) (the sensors' third number) in the kernel's precision (``env.dtype``); coupling
    (P,) int64; value (P,) float64; ``steps`` T, ``hidden`` H and ``obs_dim`` D; sensor_range, obs_radius, v_max and
    w_max (radians) in the kernel's precision; ``speed_mode`` and ``reward_mode`` the indices of ``env.speed`` and
    ``env.reward`` in :mod:`~rovermarl.env.kernel.rules`; ``layout`` (E, K) float64, what the initial conditions
    draw per episode besides the rovers' starts (K = 0 for the paper's world; ``World.kernel_for`` sets it per call);
    ``extra``, a tuple of a world plug-in's own arrays and numbers (``World.kernel_extra``; empty here); ``rows``
    (N, D) int64, each rover's input rows that may be nonzero, increasing, then -1 (``World.input_rows``, from the
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


def build(world) -> KernelWorld:
    """The record of ``world`` (a :class:`~rovermarl.env.World`, ``World.kernel``): its POIs, readings and sizes in
    the kernel's precision (``env.dtype``), with an empty layout (``World.kernel_for`` sets the initial conditions')
    and the plug-in's ``kernel_extra``, ``input_rows`` and ``state_dims``."""
    f = np.dtype(world.dtype).type
    return KernelWorld(
        world.poi_xy.astype(f), world.poi_sensor_type.astype(f), np.array(world.coupling, dtype=np.int64),
        np.array(world.value, dtype=np.float64), world.steps, world.policy.hidden, world.obs_dim,
        f(world.sensor_range), f(world.obs_radius), f(world.v_max), f(world.w_max), SPEEDS.index(world.speed),
        REWARDS.index(world.reward), np.empty((0, world.layout_dim)), world.kernel_extra(), world.input_rows(),
        world.state_dims())
