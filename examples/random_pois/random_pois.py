"""POIs drawn per episode inside a ring: a world plug-in, one module plus one yaml (``env/random_pois.yaml``).

The paper's world, except that every initial condition also draws where the POIs are: POI ``j`` uniformly (by area)
in the ring ``ring_inner <= |xy| <= ring_outer`` (its coupling and value as the setup says). A policy cannot
memorise places: it must steer by its POI sensors. Held-out scores (fresh initial conditions, so fresh POI layouts)
show whether it did. The POIs of an episode are its ``layout`` (2P numbers), stored with the initial conditions.

Run it from the repository root (``python -m`` puts the current directory on the import path)::

    python -m rovermarl.train env=random_pois hydra.searchpath=[file://examples/random_pois] generations=200 seeds=2

======================== ==============================================================================
Parameters (``env.*``)   the paper's world's, and ``ring_inner``, ``ring_outer``; ``reward: final`` only
Observation              the paper's: 3P + 2N numbers (38)
Layout                   (2P,) per episode: the POIs' x, y
Hooks                    ``sense`` and the reward read the episode's POIs; ``move`` is the paper's
Not measured             occupancy and C8 switches (they read fixed POIs: ``fixed_pois = False``)
CCEA D and D++           counterfactual teams scored by ``episode_return(xy, layout)``, on each episode's POIs
======================== ==============================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rovermarl.worlds import FAST, Hooks, World, errors, final_only, njit, no_acc, no_step, reward_at, sense_at


@njit(inline="always", **FAST)
def sense(x, y, sin_h, cos_h, n, w, s, obs):
    """The paper's sensors, each POI where the episode's layout puts it (pair ``q = i*E + e`` is episode ``e``)."""
    return sense_at(x, y, sin_h, cos_h, n, w.layout, w.poi_type, w.sensor_range, obs)


@njit(inline="always", **FAST)
def score_end(w, xy, acc, returns, s):
    """The paper's reward rule on the episode's POIs: xy (E, N, 2) after the last step."""
    reward_at(xy, w.layout, w.coupling, w.value, w.obs_radius, returns)


class RandomPois(World):
    """The paper's world with the POIs drawn per episode in a ring (``ring_inner`` to ``ring_outer``).

    >>> w = RandomPois(coupling=(1,) * 10, value=(1.0,) * 10)
    >>> ic = w.initial_conditions(seed=0, n=3)
    >>> ic.layout.shape, bool((np.hypot(*w.poi_positions(ic.layout[0]).T) >= 8.0).all())
    ((3, 20), True)
    """

    @dataclass(frozen=True)
    class Params(World.Params):
        ring_inner: float = 8.0
        ring_outer: float = 14.0

        def check(self) -> None:
            errors.number("env.ring_inner", self.ring_inner, 0)
            errors.number("env.ring_outer", self.ring_outer, self.ring_inner)
            if self.reward != "final":
                raise errors.ConfigError("env.reward", self.reward, "random_pois scores the final positions only: "
                                         "final")

    hooks = Hooks(sense=sense, stepwise=final_only, score_start=no_acc, score_step=no_step,
                  score_end=score_end)                   # the paper's motion and checks
    fixed_pois = False

    @property
    def layout_dim(self) -> int:
        return 2 * self.n_pois

    def draw_layout(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, 2P): each POI uniform by area in the ring, drawn after the rovers' starts."""
        r = np.sqrt(rng.uniform(self.ring_inner ** 2, self.ring_outer ** 2, size=(n, self.n_pois)))
        angle = rng.uniform(0.0, 2 * np.pi, size=(n, self.n_pois))
        return np.stack([r * np.cos(angle), r * np.sin(angle)], axis=-1).reshape(n, 2 * self.n_pois)

    def poi_positions(self, layout=None) -> np.ndarray:
        """The episode's POIs (P, 2); without a layout the paper's circle (a placeholder for figures' legends)."""
        return self.poi_xy if layout is None else np.asarray(layout, np.float64).reshape(self.n_pois, 2)

    def team_return(self, xy):
        raise ValueError("random_pois: team_return needs an episode's POIs; use episode_return(xy, layout)")

    def draw(self, ax, layout=None) -> None:
        from matplotlib.patches import Circle
        for r in (self.ring_inner, self.ring_outer):
            ax.add_patch(Circle((0.0, 0.0), r, fill=False, ec="0.6", lw=0.6, ls="--", zorder=0))

    def log_static(self, rec, layout=None) -> None:
        import rerun as rr
        theta = np.linspace(0, 2 * np.pi, 129)
        rings = [r * np.stack([np.cos(theta), np.sin(theta)], axis=1) for r in (self.ring_inner, self.ring_outer)]
        rec.log("world/ring", rr.LineStrips2D(rings, colors=[150, 150, 150], radii=-1.0, draw_order=5.0),
                static=True)
