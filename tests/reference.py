"""SPEC sections 1-4 in plain numpy (no numba): the tests' oracle for the compiled kernel, and the baseline that
``benchmarks/throughput.py`` measures it against.

Written for reading, not speed: every rule is one vectorised expression over episodes and rovers, with libm
``arctan2``/``tanh``/``sin``/``cos``. It reads only a World's public fields. Its returns equal the kernel's; its
trajectories agree to rounding (the kernel's branchless math is within 2 ulp of libm, and differences grow over the
steps).

The world options of SPEC section 8 (``world.reward``, ``world.speed``, ``world.poi_type``) are transcribed here
too, from the SPEC's words, not from the kernel.

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
    """Observations (SPEC section 3): xy (E, N, 2), heading (E, N) -> (E, N, D).

    Per POI ``[d / range, bearing / pi, type]`` (type: ``coupling - 1``; ``poi_type="sign"``: -1 for coupling 1,
    else +1; ``"value"``: the POI's value), then per rover ``[d / range, bearing / pi]`` (own slot
    ``[0, 0]``); a target beyond ``sensor_range`` reads ``[1, 0, 0]`` / ``[1, 0]``. The bearing is
    ``atan2(dy, dx) - heading`` wrapped to [-pi, pi).
    """
    e, n = heading.shape
    rng = world.sensor_range
    c = np.asarray(world.coupling, dtype=np.float64)
    poi_type = {"coupling": c - 1.0, "sign": np.sign(c - 1.5),
                "value": np.asarray(world.value, dtype=np.float64)}[world.poi_type]
    # POIs: offsets (E, N, P)
    dx = world.poi_xy[None, None, :, 0] - xy[:, :, None, 0]
    dy = world.poi_xy[None, None, :, 1] - xy[:, :, None, 1]
    d = np.sqrt(dx * dx + dy * dy)
    seen = d <= rng
    b = wrap(np.arctan2(dy, dx) - heading[:, :, None]) / np.pi
    poi = np.stack([np.where(seen, d / rng, 1.0), np.where(seen, b, 0.0),
                    np.where(seen, poi_type, 0.0)], axis=-1)                     # (E, N, P, 3)
    # other rovers: offset of rover m seen from rover i, (E, N_i, N_m)
    dx = xy[:, None, :, 0] - xy[:, :, None, 0]
    dy = xy[:, None, :, 1] - xy[:, :, None, 1]
    d = np.sqrt(dx * dx + dy * dy)
    seen = d <= rng
    b = wrap(np.arctan2(dy, dx) - heading[:, :, None]) / np.pi
    rov = np.stack([np.where(seen, d / rng, 1.0), np.where(seen, b, 0.0)], axis=-1)   # (E, N, N, 2)
    rov[:, np.arange(n), np.arange(n)] = 0.0                                            # own slot
    return np.concatenate([poi.reshape(e, n, -1), rov.reshape(e, n, -1)], axis=-1)


def act(world, genomes: np.ndarray, obs: np.ndarray) -> np.ndarray:
    """Actions (SPEC section 4): genomes (N, G), obs (E, N, D) -> (E, N, 2), the MLP D -> H -> 2 with tanh on both
    layers (genome layout of :mod:`rovermarl.policy`)."""
    w1, b1, w2, b2 = policy.unflatten(genomes, world.obs_dim, world.policy.hidden)   # (N,D,H) (N,H) (N,H,2) (N,2)
    hid = np.tanh(obs.transpose(1, 0, 2) @ w1 + b1[:, None, :])              # (N, E, H)
    return np.tanh(hid @ w2 + b2[:, None, :]).transpose(1, 0, 2)             # (E, N, 2)


def move(world, xy: np.ndarray, heading: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One step (SPEC section 2): turn by ``a1 * w_max``, then move ``(a0 + 1) / 2 * v_max`` (``speed="clip"``:
    ``max(a0, 0) * v_max``) along the new heading.
    xy (E, N, 2), heading (E, N), actions (E, N, 2) -> new (xy, heading)."""
    heading = heading + actions[..., 1] * world.w_max
    if world.speed == "clip":
        speed = np.maximum(actions[..., 0], 0.0) * world.v_max
    else:
        speed = (actions[..., 0] + 1.0) * 0.5 * world.v_max
    return xy + speed[..., None] * np.stack([np.cos(heading), np.sin(heading)], axis=-1), heading


def count(world, xy: np.ndarray) -> np.ndarray:
    """Rovers within ``obs_radius`` of each POI: xy (E, N, 2) -> (E, P)."""
    dx = world.poi_xy[None, None, :, 0] - xy[:, :, None, 0]
    dy = world.poi_xy[None, None, :, 1] - xy[:, :, None, 1]
    return (np.sqrt(dx * dx + dy * dy) <= world.obs_radius).sum(axis=1)


def team_return(world, xy: np.ndarray) -> np.ndarray:
    """Per-episode return of positions (SPEC section 1): xy (E, N, 2) -> (E,). POI j pays ``value[j]`` when at
    least ``coupling[j]`` rovers are within ``obs_radius`` of it."""
    return np.where(count(world, xy) >= np.asarray(world.coupling), np.asarray(world.value), 0.0).sum(axis=1)


def episode_return(world, traj_xy: np.ndarray) -> np.ndarray:
    """Per-episode return under ``world.reward`` (SPEC section 8) of trajectories traj_xy (E, T+1, N, 2) -> (E,):
    ``final`` scores the last positions; ``any_step`` pays POI j once if at some step t >= 1 at least ``coupling[j]``
    rovers are within ``obs_radius`` of it; ``best_step`` / ``mean_step`` take the max / mean over t = 1..T of the
    section-1 return."""
    steps = [traj_xy[:, t] for t in range(1, traj_xy.shape[1])]
    if world.reward == "final":
        return team_return(world, steps[-1])
    if world.reward == "any_step":
        met = np.any([count(world, xy) >= np.asarray(world.coupling) for xy in steps], axis=0)   # (E, P)
        return np.where(met, np.asarray(world.value), 0.0).sum(axis=1)
    per_step = np.array([team_return(world, xy) for xy in steps])                             # (T, E)
    return per_step.max(axis=0) if world.reward == "best_step" else per_step.mean(axis=0)


def rollout(world, genomes: np.ndarray, ic, record: bool = False):
    """Run a team genomes (N, G) from ic = (xy (E, N, 2), heading (E, N)): T steps of sense, act, move.

    Returns per-episode returns (E,), or ``(xy (E, T+1, N, 2), heading (E, T+1, N), returns (E,))`` if ``record``.
    """
    xy, heading = (np.array(a, dtype=np.float64) for a in ic[:2])
    traj_xy, traj_h = [xy], [heading]
    for _ in range(world.steps):
        xy, heading = move(world, xy, heading, act(world, genomes, observe(world, xy, heading)))
        traj_xy.append(xy)
        traj_h.append(heading)
    returns = episode_return(world, np.stack(traj_xy, axis=1))
    if record:
        return np.stack(traj_xy, axis=1), np.stack(traj_h, axis=1), returns
    return returns
