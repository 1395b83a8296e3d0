"""Credit of each rover for a team's episodes: the global reward G, the difference reward D (Agogino and Tumer) and
D++ (Rahmattalabi et al., 2016), from trajectories xy (E, T+1, N, 2) and the episodes' layout (E, K) as
:meth:`World.rollout <rovermarl.env.World.rollout>` returns them. Each credit is (N, E): rover i's in episode e.

- ``G``: the team return, the same for every rover.
- ``D_i = G(z) - G(z_{-i})``: the team return minus the return of the team with rover i removed.
- ``D++_i``: D_i when adding N - 1 copies of rover i (counterfactual partners on its trajectory) does not earn more
  per partner than D_i; else the gain per partner with the fewest partners ``n`` (1 <= n < N - 1) that beats the
  gain per partner with N - 1 of them, or that one if none does. ``gain(n) = (G(z + n copies of i) - G(z)) / n``.
  This is the published algorithm as the AADI lab's rover-domain code implements it.

Counterfactual teams are scored by the world's own reading (``env.reward``) through
:meth:`World.episode_return <rovermarl.env.World.episode_return>`, which takes any number of rovers, each episode on
its own layout (a world whose POIs are drawn per episode or move, ``layout_dim`` K > 0).
"""

from __future__ import annotations

import numpy as np

CREDITS = ("global", "difference", "dpp")


def _scored(world, xy: np.ndarray, layout: np.ndarray | None) -> np.ndarray:
    """The part of trajectories xy (..., T+1, N, 2) the world's reading scores: the last step under ``final`` on
    fixed POIs (counterfactual teams are then built from final positions only), else every step."""
    return xy[..., -1:, :, :] if world.reward == "final" and not _laid_out(layout) else xy


def _returns(world, xy: np.ndarray, layout: np.ndarray | None) -> np.ndarray:
    """Returns of (counterfactual) teams from :func:`_scored` trajectories (..., E, S, M, 2) -> (..., E), each
    episode e on its layout ``layout[e]`` (E, K)."""
    if _laid_out(layout):
        return world.episode_return(xy, np.broadcast_to(layout, xy.shape[:-3] + layout.shape[-1:]))
    return world.team_return(xy[..., -1, :, :]) if world.reward == "final" else world.episode_return(xy)


def _laid_out(layout: np.ndarray | None) -> bool:
    """Whether the episodes carry a layout (K > 0): then counterfactuals are scored by whole episodes."""
    return layout is not None and layout.shape[-1] > 0


def global_reward(world, xy: np.ndarray, g: np.ndarray | None = None, layout: np.ndarray | None = None) -> np.ndarray:
    """G for every rover: xy (E, T+1, N, 2) -> (N, E); ``g`` (E,) the team returns if known, ``layout`` (E, K)."""
    g = world.episode_return(xy, layout) if g is None else g
    return np.broadcast_to(g, (xy.shape[-2], g.shape[0])).copy()


def without(xy: np.ndarray) -> np.ndarray:
    """The N teams with one rover removed: xy (E, T+1, N, 2) -> (N, E, T+1, N-1, 2), team i without rover i."""
    return np.stack([np.delete(xy, i, axis=-2) for i in range(xy.shape[-2])])


def with_partners(xy: np.ndarray, n: int) -> np.ndarray:
    """The N teams with ``n`` counterfactual partners of one rover (copies of its trajectory) added:
    xy (E, T+1, N, 2) -> (N, E, T+1, N+n, 2), team i with n copies of rover i."""
    rovers = xy.shape[-2]
    own = np.moveaxis(xy, -2, 0)[:, :, :, None, :]                       # (N, E, T+1, 1, 2)
    team = np.broadcast_to(xy, (rovers, *xy.shape))
    return np.concatenate([team, np.repeat(own, n, axis=-2)], axis=-2)


def difference(world, xy: np.ndarray, g: np.ndarray | None = None, layout: np.ndarray | None = None) -> np.ndarray:
    """D: xy (E, T+1, N, 2) -> (N, E); ``g`` (E,) the team returns if known, ``layout`` (E, K) the episodes'."""
    g = world.episode_return(xy, layout) if g is None else g
    return g[None, :] - _returns(world, without(_scored(world, xy, layout)), layout)


def dpp(world, xy: np.ndarray, g: np.ndarray | None = None, layout: np.ndarray | None = None) -> np.ndarray:
    """D++: xy (E, T+1, N, 2) -> (N, E); ``g`` (E,) the team returns if known, ``layout`` (E, K) the episodes'.

    >>> from rovermarl.env import make_world
    >>> w = make_world("duo", n_rovers=2, steps=1)                                  # duo: 2 rovers needed at a POI
    >>> both = np.array([[[[0.0, 0.0], [0.0, 0.0]], [[13.0, 0.0], [12.5, 0.0]]]])  # E = 1: both end on POI 0
    >>> alone = np.array([[[[0.0, 0.0], [0.0, 0.0]], [[13.0, 0.0], [0.0, 0.0]]]])  # rover 0 alone on POI 0
    >>> global_reward(w, both).tolist(), difference(w, both).tolist()              # each is needed
    ([[3.0], [3.0]], [[3.0], [3.0]])
    >>> difference(w, alone).tolist(), dpp(w, alone).tolist()                      # D sees nothing; D++ sees 3
    ([[0.0], [0.0]], [[3.0], [0.0]])
    """
    g = world.episode_return(xy, layout) if g is None else g
    d = difference(world, xy, g, layout)
    rovers = xy.shape[-2]
    if rovers < 2:
        return d
    xy = _scored(world, xy, layout)
    gain = np.stack([(_returns(world, with_partners(xy, n), layout) - g[None, :]) / n for n in range(1, rovers)])
    most = out = gain[-1]                                                 # (N, E): N - 1 partners
    for n in range(rovers - 2, 0, -1):                # the fewest partners that beat N - 1: written last, so kept
        out = np.where(gain[n - 1] > most, gain[n - 1], out)
    return np.where(most <= d, d, out)


def credit(name: str, world, xy: np.ndarray, g: np.ndarray | None = None,
           layout: np.ndarray | None = None) -> np.ndarray:
    """The credit ``name`` (one of :data:`CREDITS`): xy (E, T+1, N, 2), the episodes' ``layout`` (E, K) -> (N, E)."""
    return {"global": global_reward, "difference": difference, "dpp": dpp}[name](world, xy, g, layout)
