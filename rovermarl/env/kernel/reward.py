"""The reward (SPEC section 1) and its per-step readings (SPEC section 8), numba, on batched arrays.

:func:`observers` counts the rovers within ``obs_radius`` of each POI (:func:`~rovermarl.env.kernel.rules.within`,
the one radius test), :func:`payout` is the one reward rule, :func:`reward` scores positions after the last step
(``env.reward=final``); :func:`fold` and :func:`settle` score every step for the other readings.

Shapes: E episodes, N rovers, P POIs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rovermarl.env.kernel.rules import ANY_STEP, BEST_STEP, within


@njit(inline="always", cache=True)
def observers(xy, poi_xy, radius, out):
    """Rovers observing each POI: out[e, j] += rovers of episode e :func:`within` ``radius`` of POI j.
    xy (E, N, 2), poi_xy (P, 2), out (E, P) integers.

    >>> import numpy as np
    >>> out = np.zeros((1, 2), dtype=np.int64)
    >>> observers(np.array([[[12.0, 0.0], [14.0, 1.0]]]), np.array([[13.0, 0.0], [-13.0, 0.0]]), 2.0, out)
    >>> out.tolist()
    [[2, 0]]
    """
    if out.shape != (xy.shape[0], poi_xy.shape[0]):
        raise ValueError("observers: expected xy (E, N, 2), poi_xy (P, 2) and out (E, P)")
    for e in range(xy.shape[0]):
        for i in range(xy.shape[1]):
            for j in range(poi_xy.shape[0]):
                if within(poi_xy[j, 0], poi_xy[j, 1], xy[e, i, 0], xy[e, i, 1], radius):
                    out[e, j] += 1


@njit(inline="always", cache=True)
def payout(count, coupling, value, out):
    """The reward rule: out[e] = sum over POIs j (in index order) of ``value[j]`` if ``count[e, j] >= coupling[j]``.
    count (E, P) observers, coupling (P,), value (P,) -> out (E,).

    >>> import numpy as np
    >>> out = np.empty(1)
    >>> payout(np.array([[2, 1]]), np.array([2, 2]), np.array([3.0, 3.0]), out)
    >>> out.tolist()
    [3.0]
    """
    if out.shape[0] != count.shape[0] or coupling.shape[0] != count.shape[1] or value.shape[0] != count.shape[1]:
        raise ValueError("payout: expected count (E, P), coupling (P,), value (P,) and out (E,)")
    for e in range(count.shape[0]):
        total = 0.0
        for j in range(count.shape[1]):
            if count[e, j] >= coupling[j]:
                total += value[j]
        out[e] = total


@njit(cache=True)
def reward(xy, poi_xy, coupling, value, radius, out):
    """Team return of each episode from positions: xy (E, N, 2), poi_xy (P, 2), coupling (P,), value (P,) -> out (E,)
    (:func:`observers`, then :func:`payout`).

    >>> import numpy as np
    >>> out = np.empty(2)
    >>> reward(np.array([[[12.0, 0.0]], [[0.0, 0.0]]]), np.array([[13.0, 0.0]]), np.ones(1, np.int64), np.ones(1),
    ...        2.0, out)
    >>> out.tolist()
    [1.0, 0.0]
    """
    count = np.zeros((xy.shape[0], poi_xy.shape[0]), dtype=np.int64)
    observers(xy, poi_xy, radius, count)
    payout(count, coupling, value, out)


@njit(cache=True)
def fold(mode, xy, poi_xy, coupling, value, radius, count, step, peak, acc):
    """Fold the positions after one step into a per-step reading of ``env.reward`` (SPEC section 8; ``mode`` is its
    index in :data:`~rovermarl.env.kernel.rules.REWARDS`, not 0). xy (E, N, 2); count (E, P) int and step (E,) are
    scratch. ``any_step`` keeps each POI's most observers at one step in peak (E, P) (start at 0); ``best_step``
    keeps the best step return in acc (E,) (start at -inf); ``mean_step`` sums the step returns in acc (start at 0).
    :func:`settle` turns them into the returns.

    >>> import numpy as np
    >>> poi, c, v = np.array([[13.0, 0.0]]), np.array([2]), np.array([3.0])
    >>> count, step, peak, acc = np.zeros((1, 1), np.int64), np.empty(1), np.zeros((1, 1), np.int64), np.zeros(1)
    >>> for x in (0.0, 12.0, 0.0):                                 # two rovers meet at the duo POI at step 2 only
    ...     fold(1, np.array([[[x, 0.0], [x, 0.5]]]), poi, c, v, 2.0, count, step, peak, acc)
    >>> out = np.empty(1)
    >>> settle(1, 3, c, v, peak, acc, out)
    >>> out.tolist()                                               # any_step pays 3; final would pay 0
    [3.0]
    """
    count[:] = 0
    observers(xy, poi_xy, radius, count)
    if mode == ANY_STEP:
        for e in range(count.shape[0]):
            for j in range(count.shape[1]):
                peak[e, j] = max(peak[e, j], count[e, j])
        return
    payout(count, coupling, value, step)
    for e in range(step.shape[0]):
        acc[e] = max(acc[e], step[e]) if mode == BEST_STEP else acc[e] + step[e]


@njit(cache=True)
def settle(mode, steps, coupling, value, peak, acc, out):
    """The returns out (E,) of a per-step reading after ``steps`` calls of :func:`fold`: ``any_step`` pays each POI
    whose peak (E, P) reached its coupling; ``best_step`` the best step return acc (E,); ``mean_step`` acc / steps."""
    if mode == ANY_STEP:
        payout(peak, coupling, value, out)
    elif mode == BEST_STEP:
        out[:] = acc
    else:
        out[:] = acc / steps
