"""Rovers on batteries (tests/test_plugin_mistakes.py): each rover's charge is drawn per episode, moving spends it,
and a rover with none left stands still. A world plug-in with per-rover state, and the lines the tests break.

State ``battery`` (N*E, 2): the charge left and the charge spent.
"""

from __future__ import annotations

from dataclasses import dataclass

from rovermarl.worlds import FAST, Hooks, State, World, like, move_flat, njit


@njit(inline="always", **FAST)
def begin(x, y, n, w, s):
    """Each rover's charge from the layout (per episode, one number per rover)."""
    bat = s[0]
    e_count = w.layout.shape[0]
    for q in range(x.shape[0]):
        bat[q, 0] = w.layout[q % e_count, q // e_count]
        bat[q, 1] = 0.0


@njit(inline="always", **FAST)
def move(x, y, heading, sin_h, cos_h, a0, a1, w, s):
    """The paper's motion at the speed the charge allows; each step spends |speed| of it."""
    bat = s[0]
    for q in range(x.shape[0]):
        if bat[q, 0] <= 0.0:
            a0[q] = like(a0[q], 0.0)
    move_flat(x, y, heading, sin_h, cos_h, a0, a1, w.v_max, w.w_max, w.speed_mode)  # MOVE
    for q in range(x.shape[0]):
        used = abs(a0[q])
        bat[q, 0] -= used
        bat[q, 1] += used  # SPENT


class Battery(World):
    @dataclass(frozen=True)
    class Params(World.Params):
        charge_low: float = 3.0
        charge_high: float = 10.0

    hooks = Hooks(begin=begin, move=move)
    state = (State("battery", "rover", 2, "float"),)

    @property
    def layout_dim(self) -> int:
        return self.n_rovers

    def draw_layout(self, rng, n):
        return rng.uniform(self.charge_low, self.charge_high, size=(n, self.n_rovers))
