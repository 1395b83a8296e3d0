"""The paper's world as a plug-in: every hook the paper's own under a new name (``benchmarks/plugin_loop.py``)."""

from __future__ import annotations

from rovermarl.worlds import FAST, Hooks, World, njit, rover_hooks


@njit(inline="always", **FAST)
def twin_sense(x, y, sin_h, cos_h, n, w, s, obs):
    return rover_hooks.sense(x, y, sin_h, cos_h, n, w, s, obs)


@njit(inline="always", **FAST)
def twin_move(x, y, heading, sin_h, cos_h, a0, a1, w, s):
    rover_hooks.move(x, y, heading, sin_h, cos_h, a0, a1, w, s)


@njit(inline="always", cache=True)
def twin_end(w, xy, acc, returns, s):
    rover_hooks.score_end(w, xy, acc, returns, s)


class Twin(World):
    """The paper's world, its rollout generated around hooks of another module (``compose``)."""

    hooks = Hooks(sense=twin_sense, move=twin_move, score_end=twin_end)
