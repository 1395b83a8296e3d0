"""Circular obstacles that rovers cannot enter: a world plug-in, one module plus one yaml (``env/obstacles.yaml``).

The paper's world with ``obstacles``: discs ``(x, y, radius)`` between the start and the POIs. A rover whose step
would end inside a disc slides to its boundary (its position is pushed out along the disc's radius). Each rover
senses every obstacle (an extra observation block after the paper's: the distance to the disc's edge / sensor range
and the bearing to its centre / pi, ``[1, 0]`` beyond the sensor range). The figures and the recording draw the discs.

Run it from the repository root (``python -m`` puts the current directory on the import path)::

    python -m rovermarl.train env=obstacles hydra.searchpath=[file://examples/obstacles] generations=200 seeds=2

======================== ==============================================================================
Parameters (``env.*``)   the paper's world's, and ``obstacles``: a list of ``[x, y, radius]``
Observation              3P + 2N + 2M numbers (M obstacles): 46 for the paper's 10 POIs, 4 rovers, 4 discs
Hooks                    ``sense`` (the paper's sensors, then the obstacle block: the policy reads it, as
                         ``obs_blocks`` declares it), ``move`` (then slide out); the reward is the paper's
======================== ==============================================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rovermarl.worlds import FAST, Hooks, World, bearing, errors, like, move_flat, njit, reading, sense_flat


@njit(inline="always", **FAST)
def sense(x, y, sin_h, cos_h, n, w, s, obs):
    """The paper's sensors (rows 0..3P+2N-1), then 2 rows per obstacle."""
    ranged = sense_flat(x, y, sin_h, cos_h, n, w.poi_xy, w.poi_type, w.sensor_range, obs)
    discs = w.extra[0]
    ne = x.shape[0]
    row = 3 * w.poi_xy.shape[0] + 2 * n
    inv_pi = like(w.sensor_range, 1.0 / math.pi)
    for m in range(discs.shape[0]):
        o = (row + 2 * m) * ne
        for q in range(ne):
            dx = discs[m, 0] - x[q]
            dy = discs[m, 1] - y[q]
            d = max(math.sqrt(dx * dx + dy * dy) - discs[m, 2], like(dx, 0.0))    # to the disc's edge
            b = bearing(dx, dy, cos_h[q], sin_h[q], False)
            obs[o + q], obs[o + ne + q], _ = reading(d, w.sensor_range, d / w.sensor_range, b * inv_pi, 0.0)
    return ranged


@njit(inline="always", **FAST)
def move(x, y, heading, sin_h, cos_h, a0, a1, w, s):
    """The paper's motion, then each rover inside a disc slides out to its edge (discs should not overlap)."""
    move_flat(x, y, heading, sin_h, cos_h, a0, a1, w.v_max, w.w_max, w.speed_mode)
    discs = w.extra[0]
    for q in range(x.shape[0]):
        for m in range(discs.shape[0]):
            dx = x[q] - discs[m, 0]
            dy = y[q] - discs[m, 1]
            d = math.sqrt(dx * dx + dy * dy)
            r = discs[m, 2]
            if d < r:
                if d == 0:                            # at the centre: out along +x
                    dx, d = like(dx, 1.0), like(dx, 1.0)
                x[q] = discs[m, 0] + dx * (r / d)
                y[q] = discs[m, 1] + dy * (r / d)


class Obstacles(World):
    """The paper's world with circular obstacles (``obstacles``: ``[x, y, radius]`` each).

    >>> import numpy as np
    >>> w = Obstacles(coupling=(1,) * 10, value=(1.0,) * 10, obstacles=((0.0, 6.0, 1.0),))
    >>> w.obs_dim, [name for name, low, high in w.obs_blocks()]
    (40, ['poi', 'rover', 'obstacle'])
    """

    @dataclass(frozen=True)
    class Params(World.Params):
        obstacles: tuple = ((6.5, 0.0, 1.5), (0.0, 6.5, 1.5), (-6.5, 0.0, 1.5), (0.0, -6.5, 1.5))

        def check(self) -> None:
            discs = self.obstacles
            if not isinstance(discs, (list, tuple)):
                raise errors.ConfigError("env.obstacles", discs, "must be a list of [x, y, radius]")
            for m, disc in enumerate(discs):
                if not isinstance(disc, (list, tuple)) or len(disc) != 3:
                    raise errors.ConfigError(f"env.obstacles[{m}]", disc, "must be [x, y, radius]")
                errors.number(f"env.obstacles[{m}][0]", disc[0])
                errors.number(f"env.obstacles[{m}][1]", disc[1])
                errors.number(f"env.obstacles[{m}][2]", disc[2], 0, lo_open=True)
            object.__setattr__(self, "obstacles", tuple(tuple(float(v) for v in disc) for disc in discs))

    hooks = Hooks(sense=sense, move=move)                  # the paper's reward and checks

    def kernel_extra(self) -> tuple:
        return (np.array(self.obstacles, dtype=self.dtype).reshape(-1, 3),)

    def obs_blocks(self):
        m = 2 * len(self.obstacles)
        return [*super().obs_blocks(), ("obstacle", -np.ones(m), np.ones(m))]

    def draw(self, ax, layout=None) -> None:
        from matplotlib.patches import Circle
        for x, y, r in self.obstacles:
            ax.add_patch(Circle((x, y), r, fc="0.55", ec="0.3", lw=0.8, zorder=1))

    def log_static(self, rec, layout=None) -> None:
        import rerun as rr
        theta = np.linspace(0, 2 * np.pi, 65)
        rings = [np.stack([x + r * np.cos(theta), y + r * np.sin(theta)], axis=1) for x, y, r in self.obstacles]
        rec.log("world/obstacles", rr.LineStrips2D(rings, colors=[128, 128, 128], radii=-2.0, draw_order=15.0),
                static=True)
