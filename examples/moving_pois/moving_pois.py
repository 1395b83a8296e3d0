"""POIs that drift, each on its own circle at its own speed: a world plug-in with memory, one module plus one yaml.

The paper's world, except that POI ``j`` circles its paper position at radius ``drift_radius``, starting at a phase
and moving at a speed (``speed_low`` to ``speed_high`` per step, either way round) that every initial condition
draws anew. Where the POIs are is the world's per-episode state (``state``): the hook ``begin`` places them at the
episode's start, ``tick`` moves them after every step; the sensors and the reward read them there. The recording
draws them where they are at each step.

Run it from the repository root (``python -m`` puts the current directory on the import path)::

    python -m rovermarl.train env=moving_pois hydra.searchpath=[file://examples/moving_pois] generations=200 seeds=2

======================== ==============================================================================
Parameters (``env.*``)   the paper's world's, and ``drift_radius``, ``speed_low``, ``speed_high``; ``reward: final``
Observation              the paper's: 3P + 2N numbers (38), the POIs where they are now
Layout                   (2P,) per episode: each POI's phase and angular speed (radians per step)
State                    ``poi`` (E, 2P): the POIs now; ``t`` (E, 1): the step
Hooks                    ``begin``, ``tick`` (the POIs), ``sense`` and the reward read them; ``move`` is the paper's
======================== ==============================================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rovermarl.worlds import FAST, Hooks, State, World, errors, final_only, njit, no_acc, no_step, reward_at, sense_at


@njit(inline="always", **FAST)
def place(w, s, dt):
    """Every episode's step ``t`` on by ``dt`` (0: to 0), and its POIs there: centre + radius * (cos, sin)(phase +
    speed * t) (float64)."""
    pois, t = s
    centres, radius = w.extra
    for e in range(t.shape[0]):
        t[e, 0] = t[e, 0] + dt if dt else 0
        for j in range(centres.shape[0]):
            a = w.layout[e, 2 * j] + w.layout[e, 2 * j + 1] * t[e, 0]
            pois[e, 2 * j] = centres[j, 0] + radius * math.cos(a)
            pois[e, 2 * j + 1] = centres[j, 1] + radius * math.sin(a)


@njit(inline="always", **FAST)
def begin(x, y, n, w, s):
    """Step 0: each POI at its phase."""
    place(w, s, 0)


@njit(inline="always", **FAST)
def tick(x, y, n, w, s):
    """After each move: one step on."""
    place(w, s, 1)


@njit(inline="always", **FAST)
def sense(x, y, sin_h, cos_h, n, w, s, obs):
    """The paper's sensors, each POI where it is now."""
    return sense_at(x, y, sin_h, cos_h, n, s[0], w.poi_type, w.sensor_range, obs)


@njit(inline="always", **FAST)
def score_end(w, xy, acc, returns, s):
    """The paper's reward rule, each POI where it is after the last step."""
    reward_at(xy, s[0], w.coupling, w.value, w.obs_radius, returns)


class MovingPois(World):
    """The paper's world with each POI drifting on a circle around its place (``drift_radius``) at a speed drawn
    per episode.

    >>> w = MovingPois(coupling=(1,) * 10, value=(1.0,) * 10)
    >>> ic = w.initial_conditions(seed=0, n=2)
    >>> path = w.poi_path(ic.layout[0])                                     # (T+1, P, 2)
    >>> path.shape, bool(np.allclose(np.hypot(*(path - w.poi_xy).T), w.drift_radius))
    ((16, 10, 2), True)
    """

    @dataclass(frozen=True)
    class Params(World.Params):
        drift_radius: float = 2.5
        speed_low: float = 0.1
        speed_high: float = 0.4

        def check(self) -> None:
            errors.number("env.drift_radius", self.drift_radius, 0, lo_open=True)
            errors.number("env.speed_low", self.speed_low, 0)
            errors.number("env.speed_high", self.speed_high, self.speed_low)
            if self.reward != "final":
                raise errors.ConfigError("env.reward", self.reward, "moving_pois scores the final positions only: "
                                         "final")

    hooks = Hooks(sense=sense, begin=begin, tick=tick, stepwise=final_only, score_start=no_acc, score_step=no_step,
                  score_end=score_end)                   # the paper's motion and checks
    state = (State("poi", "episode", "layout_dim", "float64"), State("t", "episode", 1, "int64"))
    fixed_pois = False

    @property
    def layout_dim(self) -> int:
        return 2 * self.n_pois

    def kernel_extra(self) -> tuple:
        return np.ascontiguousarray(self.poi_xy, np.float64), float(self.drift_radius)

    def draw_layout(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, 2P): each POI's phase in [0, 2 pi) and angular speed (radians per step, either sign)."""
        phase = rng.uniform(0.0, 2 * np.pi, size=(n, self.n_pois))
        speed = rng.uniform(self.speed_low, self.speed_high, size=(n, self.n_pois))
        speed *= rng.choice([-1.0, 1.0], size=(n, self.n_pois)) / self.drift_radius
        return np.stack([phase, speed], axis=-1).reshape(n, 2 * self.n_pois)

    def poi_track(self, layout=None):
        return None if layout is None else self.poi_path(layout)

    def poi_path(self, layout) -> np.ndarray:
        """(T+1, P, 2): where the POIs of an episode with ``layout`` (2P,) are at each step (numpy)."""
        phase, speed = np.asarray(layout, np.float64).reshape(self.n_pois, 2).T
        a = phase + speed * np.arange(self.steps + 1)[:, None]                 # (T+1, P)
        return self.poi_xy + self.drift_radius * np.stack([np.cos(a), np.sin(a)], axis=-1)

    def poi_positions(self, layout=None) -> np.ndarray:
        """The POIs after the last step (P, 2) (where the reward reads them); without a layout the paper's."""
        return self.poi_xy if layout is None else self.poi_path(layout)[-1]

    def team_return(self, xy):
        raise ValueError("moving_pois: team_return needs an episode's POIs; use episode_return(xy, layout)")

    def draw(self, ax, layout=None) -> None:
        from matplotlib.patches import Circle
        for x, y in self.poi_xy:
            ax.add_patch(Circle((x, y), self.drift_radius, fill=False, ec="0.6", lw=0.6, ls=":", zorder=0))

    def log_static(self, rec, layout=None) -> None:
        import rerun as rr
        theta = np.linspace(0, 2 * np.pi, 65)
        rings = [np.stack([x + self.drift_radius * np.cos(theta), y + self.drift_radius * np.sin(theta)], axis=1)
                 for x, y in self.poi_xy]
        rec.log("world/drift", rr.LineStrips2D(rings, colors=[150, 150, 150], radii=-1.0, draw_order=5.0),
                static=True)
