"""Plain numpy rollout of a team, vectorised over episodes and rovers (no numba).

It is the baseline the compiled kernel is measured against (``benchmarks/throughput.py``) and a
readable reference for its trajectories (``tests/test_kernel_math.py``). Same world, same genome and
observation layout as ``rovermarl.env.World`` (SPEC sections 1-4).

Shapes: E episodes, N rovers, P POIs, D = 3P + 2N observation size, H hidden units, T steps.
"""

from __future__ import annotations

import numpy as np

from rovermarl import policy


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    r = a - 2 * np.pi * np.floor((a + np.pi) / (2 * np.pi))
    r = np.where(r >= np.pi, r - 2 * np.pi, r)        # rounding in the floor can land one ulp outside
    return np.where(r < -np.pi, r + 2 * np.pi, r)


def observe(world, xy: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Observations: xy (E, N, 2), heading (E, N) -> (E, N, D)."""
    e, n = heading.shape
    rng = world.sensor_range
    # POIs: offsets (E, N, P)
    dx = world.poi_xy[None, None, :, 0] - xy[:, :, None, 0]
    dy = world.poi_xy[None, None, :, 1] - xy[:, :, None, 1]
    d = np.sqrt(dx * dx + dy * dy)
    seen = d <= rng
    b = wrap(np.arctan2(dy, dx) - heading[:, :, None]) / np.pi
    poi = np.stack([np.where(seen, d / rng, 1.0), np.where(seen, b, 0.0),
                    np.where(seen, world._type, 0.0)], axis=-1)                 # (E, N, P, 3)
    # other rovers: offset of rover m seen from rover i, (E, N_i, N_m)
    dx = xy[:, None, :, 0] - xy[:, :, None, 0]
    dy = xy[:, None, :, 1] - xy[:, :, None, 1]
    d = np.sqrt(dx * dx + dy * dy)
    seen = d <= rng
    b = wrap(np.arctan2(dy, dx) - heading[:, :, None]) / np.pi
    rov = np.stack([np.where(seen, d / rng, 1.0), np.where(seen, b, 0.0)], axis=-1)   # (E, N, N, 2)
    rov[:, np.arange(n), np.arange(n)] = 0.0                                            # own slot
    return np.concatenate([poi.reshape(e, n, -1), rov.reshape(e, n, -1)], axis=-1)


def team_return(world, xy: np.ndarray) -> np.ndarray:
    """Per-episode return of final positions xy (E, N, 2) -> (E,)."""
    dx = world.poi_xy[None, None, :, 0] - xy[:, :, None, 0]
    dy = world.poi_xy[None, None, :, 1] - xy[:, :, None, 1]
    count = (np.sqrt(dx * dx + dy * dy) <= world.obs_radius).sum(axis=1)   # (E, P)
    return np.where(count >= world._coupling, world._value, 0.0).sum(axis=1)


def rollout(world, genomes: np.ndarray, ic, record: bool = False):
    """Run a team genomes (N, P) from ic = (xy (E, N, 2), heading (E, N)).

    Returns per-episode returns (E,), or ``(xy (E, T+1, N, 2), heading (E, T+1, N), returns (E,))``
    if ``record``.
    """
    xy, heading = (np.array(a, dtype=np.float64) for a in ic)
    w1, b1, w2, b2 = policy.unflatten(genomes, world.obs_dim, world.hidden)   # (N,D,H) (N,H) (N,H,2) (N,2)
    traj_xy, traj_h = [xy], [heading]
    for _ in range(world.steps):
        obs = observe(world, xy, heading).transpose(1, 0, 2)                 # (N, E, D)
        hid = np.tanh(obs @ w1 + b1[:, None, :])                             # (N, E, H)
        act = np.tanh(hid @ w2 + b2[:, None, :]).transpose(1, 0, 2)          # (E, N, 2)
        heading = heading + act[..., 1] * world.w_max
        speed = (act[..., 0] + 1.0) * 0.5 * world.v_max
        xy = xy + speed[..., None] * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
        traj_xy.append(xy)
        traj_h.append(heading)
    returns = team_return(world, xy)
    if record:
        return np.stack(traj_xy, axis=1), np.stack(traj_h, axis=1), returns
    return returns
