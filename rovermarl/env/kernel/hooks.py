"""The paper's rover world as kernel hooks (SPEC sections 1-3, 8): what :mod:`~rovermarl.env.kernel.fused` calls
each step (numba). A world is its hooks (``World.hooks``, a :class:`Hooks`); a plug-in passes its own with the same
signatures (``docs/WORLDS.md``, the one place of the contract: signatures, flat layout, a worked example).
"""

from __future__ import annotations

from typing import NamedTuple

from rovermarl.env.kernel.checks import mlp_finite
from rovermarl.env.kernel.math import FAST
from rovermarl.env.kernel.reward import fold, reward, settle, start
from rovermarl.env.kernel.rules import FINAL
from rovermarl.env.kernel.stages import from_flat, move_flat, sense_flat
from rovermarl.jit import njit


@njit(inline="always", **FAST)
def sense(x, y, sin_h, cos_h, n, w, s, obs):
    """POIs then rovers (``stages.sense_flat``): D = 3P + 2N rows."""
    return sense_flat(x, y, sin_h, cos_h, n, w.poi_xy, w.poi_type, w.sensor_range, obs)


@njit(inline="always", **FAST)
def move(x, y, heading, sin_h, cos_h, a0, a1, w, s):
    """Turn, then move (``stages.move_flat``, ``env.speed``)."""
    move_flat(x, y, heading, sin_h, cos_h, a0, a1, w.v_max, w.w_max, w.speed_mode)


@njit(inline="always", cache=True)
def score_start(w, n_ep):
    """``reward.start`` of ``env.reward`` (no per-POI state under ``final``)."""
    return start(w.reward_mode, n_ep, w.poi_xy.shape[0] if w.reward_mode != FINAL else 0)


@njit(inline="always", cache=True)
def stepwise(w):
    """A per-step reading of ``env.reward`` scores every step; ``final`` the last positions only."""
    return w.reward_mode != FINAL


@njit(inline="always", cache=True)
def score_step(w, x, y, xy, acc, s):
    """A per-step reading folds every step's positions (``reward.fold``)."""
    if w.reward_mode != FINAL:
        from_flat(x, xy[:, :, 0])
        from_flat(y, xy[:, :, 1])
        count, step, peak, total = acc
        fold(w.reward_mode, xy, w.poi_xy, w.coupling, w.value, w.obs_radius, count, step, peak, total)


@njit(inline="always", cache=True)
def score_end(w, xy, acc, returns, s):
    """``final``: the positions after the last step (SPEC section 1, ``reward.reward``); else ``reward.settle``."""
    if w.reward_mode != FINAL:
        settle(w.reward_mode, w.steps, w.coupling, w.value, acc[2], acc[3], returns)
    else:
        reward(xy, w.poi_xy, w.coupling, w.value, w.obs_radius, returns)


@njit(inline="always", cache=True)
def state_new(w, n, n_ep):
    """The paper's world keeps no state: an empty tuple (a plug-in's is written from ``World.state``)."""
    return ()


@njit(inline="always", cache=True)
def begin(x, y, n, w, s):
    """Nothing to fill."""


@njit(inline="always", cache=True)
def tick(x, y, n, w, s):
    """Nothing to advance."""


@njit(inline="always", **FAST)
def finite(genomes, w):
    """``checks.mlp_finite``."""
    return mlp_finite(genomes, w.poi_type, w.sensor_range)


class Hooks(NamedTuple):
    """A world's compiled hooks (numba functions with the signatures above); each defaults to the paper's world's,
    so a plug-in names only those it changes: ``Hooks(sense=my_sense, move=my_move)``."""

    sense: object = sense
    move: object = move
    stepwise: object = stepwise
    score_start: object = score_start
    score_step: object = score_step
    score_end: object = score_end
    finite: object = finite
    begin: object = begin
    tick: object = tick


ROVERS = Hooks()
