"""The world's rules, one home each, for one rover / one target (numba; SPEC sections 1-3): :func:`within` (the
radius test of reward, occupancy and events), :func:`poi_of`, :func:`reading` (the sensor encoding), :func:`bearing`,
:func:`turn` and :func:`speed` (the action mapping), and the codes of SPEC section 8's world options
(:data:`REWARDS`, :data:`SPEEDS`, :data:`POI_TYPES`).

Where each world option acts: ``env.speed`` in :func:`speed`; ``env.poi_type`` in the type array that the World
passes to the sensors (``World.poi_type``); ``env.reward`` in :func:`~rovermarl.env.kernel.reward.fold` (each step)
and :func:`~rovermarl.env.kernel.reward.settle` (after the last), both built on the one reward rule
:func:`~rovermarl.env.kernel.reward.payout`.

``inline="always"`` helpers take their caller's compile options: :func:`bearing`, :func:`turn` and :func:`speed`
belong in ``FAST`` (FMA-contracting) loops only; :func:`reading` does no arithmetic. :func:`within` and
:func:`poi_of` are compiled on their own without contraction, so every caller gets the same bits.
"""

from __future__ import annotations

import math

from rovermarl.env.kernel.math import FAST, atan2, like
from rovermarl.jit import njit

REWARDS = ("final", "any_step", "best_step", "mean_step")   # env.reward; the kernel's code is the index
FINAL, ANY_STEP, BEST_STEP, MEAN_STEP = range(4)
SPEEDS = ("affine", "clip")                                  # env.speed; code = index
POI_TYPES = ("coupling", "sign", "value")                    # env.poi_type (the World builds the type array)


@njit(cache=True)
def within(px, py, x, y, radius):
    """True when (x, y) is within ``radius`` of the POI at (px, py) (distance ``<= radius``).

    >>> within(13.0, 0.0, 15.0, 0.0, 2.0), within(13.0, 0.0, 15.0 + 1e-9, 0.0, 2.0)
    (True, False)
    """
    dx = px - x
    dy = py - y
    return math.sqrt(dx * dx + dy * dy) <= radius


@njit(cache=True)
def poi_of(x, y, poi_xy, radius):
    """The lowest POI index j with (x, y) :func:`within` ``radius`` of ``poi_xy[j]`` (P, 2), else -1.

    >>> import numpy as np
    >>> poi_of(12.0, 0.5, np.array([[13.0, 0.0], [-13.0, 0.0]]), 2.0), poi_of(0.0, 0.0, np.zeros((1, 2)) + 5, 2.0)
    (0, -1)
    """
    for j in range(poi_xy.shape[0]):
        if within(poi_xy[j, 0], poi_xy[j, 1], x, y, radius):
            return j
    return -1


@njit(inline="always")
def reading(d, sensor_range, dn, bn, typ):
    """Sensor encoding of a target at distance ``d``: ``(dn, bn, typ)`` if ``d <= sensor_range``, else
    ``(1, 0, 0)``; ``dn = d / range`` and ``bn = bearing / pi`` as the caller rounds them. A rover target passes
    ``typ = 0`` and keeps two numbers."""
    seen = d <= sensor_range
    zero = like(dn, 0.0)
    return (dn if seen else like(dn, 1.0)), (bn if seen else zero), (typ if seen else zero)


@njit(inline="always", **FAST)
def bearing(dx, dy, c, s, ranged=False):
    """Bearing in [-pi, pi) of world offset (dx, dy) seen by a rover with heading h, c = cos h, s = sin h: ``atan2``
    of the offset rotated into the rover frame, ``wrap(atan2(dy, dx) - h)`` up to rounding. A zero offset reads as the
    world x axis (``atan2(0, 0) = 0``), as in the SPEC formula. ``ranged``: for :func:`~rovermarl.env.kernel.math.atan2`
    (the caller has checked its promise, as ``stages.sense_flat`` does with ``checks.in_range``)."""
    zero = (dx == like(dx, 0.0)) & (dy == like(dx, 0.0))
    xr = dx * c + dy * s
    yr = dy * c - dx * s
    ms = -s
    xr = c if zero else xr
    yr = ms if zero else yr
    b = atan2(yr, xr, ranged)
    pi = like(b, math.pi)
    return -pi if b >= pi else b


@njit(inline="always", **FAST)
def turn(heading, a1, w_max):
    """New heading after action ``a1`` in [-1, 1]: ``heading + a1 * w_max`` (radians)."""
    return heading + a1 * w_max


@njit(inline="always", **FAST)
def speed(a0, v_max, mode):
    """Distance moved for action ``a0`` in [-1, 1]: ``(a0 + 1) / 2 * v_max`` (``mode`` 0, ``env.speed=affine``) or
    ``max(a0, 0) * v_max`` (1, ``clip``: the rover stands still for every ``a0 <= 0``)."""
    if mode == 1:
        return max(a0, like(a0, 0.0)) * v_max
    return (a0 + like(a0, 1.0)) * like(a0, 0.5) * v_max
