"""The paper's world as a plug-in: every hook the paper's own under a new name (``benchmarks/plugin_loop.py``)."""

from __future__ import annotations

from dataclasses import dataclass

from rovermarl.env import World
from rovermarl.env.kernel import hooks
from rovermarl.env.kernel.math import FAST
from rovermarl.jit import njit


@njit(inline="always", **FAST)
def twin_sense(x, y, sin_h, cos_h, n, w, s, obs):
    return hooks.sense(x, y, sin_h, cos_h, n, w, s, obs)


@njit(inline="always", **FAST)
def twin_move(x, y, heading, sin_h, cos_h, a0, a1, w, s):
    hooks.move(x, y, heading, sin_h, cos_h, a0, a1, w, s)


@njit(inline="always", cache=True)
def twin_end(w, xy, acc, returns, s):
    hooks.score_end(w, xy, acc, returns, s)


@dataclass(frozen=True, eq=False)
class Twin(World):
    """The paper's world, its rollout generated around hooks of another module (``compose``)."""

    hooks = hooks.Hooks(sense=twin_sense, move=twin_move, score_end=twin_end)
