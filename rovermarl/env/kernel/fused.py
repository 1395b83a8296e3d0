"""The fused team rollout (numba): the hot path of every evaluation, built from a world's hooks
(:mod:`rovermarl.env.kernel.hooks`) and the MLP stage on the flat layout of :mod:`rovermarl.env.kernel.stages`, with
all buffers allocated once per call; and the batch-first step functions an environment steps with. For a world
plug-in, :mod:`rovermarl.env.kernel.compose` compiles a copy of this module with the plug-in's hooks in place of the
line marked ``# hooks``: one source, every world.
"""

from __future__ import annotations

import numpy as np

from rovermarl.env.kernel.hooks import (  # hooks
    begin,
    finite,
    move,
    score_end,
    score_start,
    score_step,
    sense,
    state_new,
    stepwise,
    tick,
)
from rovermarl.env.kernel.lanes import in_precision, sane_teams, tile_flat, tile_rows
from rovermarl.env.kernel.math import FAST, sincos_all
from rovermarl.env.kernel.record import KernelWorld
from rovermarl.env.kernel.reward import score
from rovermarl.env.kernel.stages import act_flat, flat_pose, from_flat, to_flat
from rovermarl.jit import njit


@njit(**FAST)
def rollout(genomes, xy0, heading0, w, returns, traj_xy, traj_heading, final_xy):
    """Run E episodes of T steps of one team in the world ``w`` (a :class:`KernelWorld`): genomes (N, G) one row per
    rover, xy0 (E, N, 2), heading0 (E, N) -> the per-episode team returns (E,) in ``returns``. genomes (B*N, G) are B
    teams side by side in the lanes (:mod:`~rovermarl.env.kernel.lanes`) on the same E initial conditions: then the
    returns, and the trajectories and final positions if recorded, have B*E rows (team b's from ``b*E``). The dynamics
    run in the precision of ``genomes``, ``xy0``, ``heading0`` and ``w``'s floats (all float64, or all float32 under
    ``env.dtype=float32``); returns and trajectories are float64. The states go to ``traj_xy`` (E, T+1, N, 2) and
    ``traj_heading`` (E, T+1, N), the final positions to ``final_xy`` (E, N, 2), unless their first axis is
    zero-sized. Each step: all rovers sense, all act, then each turns and moves (the hooks ``sense``, ``act_flat``,
    ``move``), then ``score_step`` (where ``stepwise``); after the last step ``score_end`` gives the returns."""
    _rollout(genomes, xy0, heading0, returns, traj_xy, traj_heading, final_xy, w.poi_xy, w.poi_type, w.coupling,
             w.value, w.steps, w.hidden, w.obs_dim, w.sensor_range, w.obs_radius, w.v_max, w.w_max, w.speed_mode,
             w.reward_mode, w.layout, w.extra, w.rows, w.state_dims)


@njit(**FAST)
def _rollout(genomes, xy0, heading0, returns, traj_xy, traj_heading, final_xy, poi_xy, poi_type, coupling, value,
             steps, hidden, obs_dim, sensor_range, obs_radius, v_max, w_max, speed_mode, reward_mode, layout, extra,
             rows, state_dims):
    """:func:`rollout` with the record's fields as arguments of their own, rebuilt into ``w`` here: compiled so, the
    loop runs 5-10% faster than on a record argument (measured side by side: LLVM then sees plain arrays)."""
    per, n = heading0.shape
    teams = genomes.shape[0] // n                      # B teams side by side: n_ep = B*E lanes of episodes
    n_ep = teams * per
    layout = tile_rows(layout, teams) if teams > 1 and layout.shape[0] == per else layout   # one row per lane
    w = KernelWorld(poi_xy, poi_type, coupling, value, steps, hidden, obs_dim, sensor_range, obs_radius, v_max, w_max,
                    speed_mode, reward_mode, layout, extra, rows, state_dims)
    ne = n * n_ep
    record = traj_xy.shape[0] == n_ep
    d, hidden = w.obs_dim, w.hidden
    state = np.empty((7, ne), dtype=xy0.dtype)         # the world's state in the kernel's precision (env.dtype)
    x, y, heading, sin_h, cos_h, a0, a1 = state[0], state[1], state[2], state[3], state[4], state[5], state[6]
    obs, scratch = np.empty(d * ne, dtype=xy0.dtype), np.empty(d, dtype=np.int64)
    hid, cand, g = np.empty((hidden + 2) * per, dtype=xy0.dtype), w.rows, genomes
    tile_flat(xy0[:, :, 0], teams, x)
    tile_flat(xy0[:, :, 1], teams, y)
    tile_flat(heading0, teams, heading)
    if record:
        from_flat(x, traj_xy[:, 0, :, 0])
        from_flat(y, traj_xy[:, 0, :, 1])
        from_flat(heading, traj_heading[:, 0])
    sincos_all(heading, sin_h, cos_h)
    s = state_new(w, n, n_ep)                          # the world's per-episode state (World.state), this call's own
    begin(x, y, n, w, s)
    sums_finite = finite(genomes, w)                   # with each step's ranged sensing: the MLP's sums are finite
    xy = np.empty((n_ep, n, 2))                         # positions for the reward: float64 always
    acc = score_start(w, n_ep)
    each_step = stepwise(w)                            # measured: a score_step call left in the loop costs 5-10%
    for t in range(w.steps):
        ranged = sense(x, y, sin_h, cos_h, n, w, s, obs)
        act_flat(g, obs, cand, n_ep, hidden, hid, scratch, a0, a1, sums_finite and ranged)
        move(x, y, heading, sin_h, cos_h, a0, a1, w, s)
        tick(x, y, n, w, s)
        if record:
            from_flat(x, traj_xy[:, t + 1, :, 0])
            from_flat(y, traj_xy[:, t + 1, :, 1])
            from_flat(heading, traj_heading[:, t + 1])
        if each_step:
            score_step(w, x, y, xy, acc, s)
    from_flat(x, xy[:, :, 0])
    from_flat(y, xy[:, :, 1])
    if final_xy.shape[0] == n_ep:                      # (no slice assignment: its shape check compiles for seconds)
        from_flat(x, final_xy[:, :, 0])
        from_flat(y, final_xy[:, :, 1])
    score_end(w, xy, acc, returns, s)


# ---- batch-first steps: an environment's (PettingZoo, vectorised), the rollout's hooks one call at a time ----------

@njit(**FAST)
def state_of(xy, w):
    """The world's state (``World.state``) of E episodes whose rovers start at xy (E, N, 2): allocated, then filled
    by the hook ``begin``; one per environment, carried from step to step (an empty tuple for a world without)."""
    n_ep, n = xy.shape[0], xy.shape[1]
    flat = np.empty((2, n * n_ep), dtype=xy.dtype)
    to_flat(xy[:, :, 0], flat[0])
    to_flat(xy[:, :, 1], flat[1])
    s = state_new(w, n, n_ep)
    begin(flat[0], flat[1], n, w, s)
    return s


@njit(**FAST)
def observe(xy, heading, w, s, out):
    """Observations of the world ``w``'s hook ``sense`` with the state ``s`` (:func:`state_of`): xy (E, N, 2), heading
    (E, N) -> out (E, N, D), in the precision of xy."""
    n_ep, n = heading.shape
    ne = n * n_ep
    state = flat_pose(xy, heading, 5)
    obs = np.empty(w.obs_dim * ne, dtype=xy.dtype)
    sense(state[0], state[1], state[3], state[4], n, w, s, obs)
    for k in range(w.obs_dim):
        from_flat(obs[k * ne:(k + 1) * ne], out[:, :, k])


@njit(**FAST)
def sensed_rows(xy, heading, w, s, extra):
    """How many rows of the observation the hook ``sense`` fills: it writes into D + ``extra`` rows of NaN, and a row
    counts when every entry of it is a number. xy (E, N, 2), heading (E, N) (``trial.check_sense``)."""
    n_ep, n = heading.shape
    ne = n * n_ep
    state = flat_pose(xy, heading, 5)
    obs = np.full((w.obs_dim + extra) * ne, np.nan, dtype=xy.dtype)
    sense(state[0], state[1], state[3], state[4], n, w, s, obs)
    filled = np.zeros(w.obs_dim + extra, dtype=np.bool_)
    for k in range(w.obs_dim + extra):
        filled[k] = not np.isnan(obs[k * ne:(k + 1) * ne]).any()
    return filled


@njit(**FAST)
def step(xy, heading, actions, w, s):
    """One step of the hooks ``move`` and ``tick``, in place: xy (E, N, 2), heading (E, N), actions (E, N, 2) (a0, a1
    in [-1, 1]), the state ``s`` (:func:`state_of`)."""
    _moved(xy, heading, actions, w, s)


@njit(**FAST)
def _moved(xy, heading, actions, w, s):
    """:func:`step`'s work; returns its flat state after the move (x, y, heading, sin, cos, a0, a1: (7, N*E), as
    ``stages.flat_pose``), for :func:`env_step`."""
    n = heading.shape[1]
    state = flat_pose(xy, heading, 7)
    to_flat(actions[:, :, 0], state[5])
    to_flat(actions[:, :, 1], state[6])
    move(state[0], state[1], state[2], state[3], state[4], state[5], state[6], w, s)
    tick(state[0], state[1], n, w, s)
    from_flat(state[0], xy[:, :, 0])
    from_flat(state[1], xy[:, :, 1])
    from_flat(state[2], heading)
    return state


@njit(cache=True)
def returns_of(xy, w, out):
    """Episode returns from trajectories: xy (E, T+1, N, 2) float64 (index 0 the start, which no reading scores)
    -> out (E,), through the hooks ``begin`` (at index 0), ``tick`` and ``score_step`` (steps 1..T) and ``score_end``
    (step T). The state follows the positions only (a world whose ``move`` changes the state from the actions is
    scored so only where its reward does not read that part)."""
    n_ep, n = xy.shape[0], xy.shape[2]
    acc = score_start(w, n_ep)
    flat = np.empty((2, n * n_ep))
    scratch = np.empty((n_ep, n, 2))
    to_flat(xy[:, 0, :, 0], flat[0])
    to_flat(xy[:, 0, :, 1], flat[1])
    s = state_new(w, n, n_ep)
    begin(flat[0], flat[1], n, w, s)
    each_step = stepwise(w)
    for t in range(1, xy.shape[1]):
        to_flat(xy[:, t, :, 0], flat[0])
        to_flat(xy[:, t, :, 1], flat[1])
        tick(flat[0], flat[1], n, w, s)
        if each_step:
            score_step(w, flat[0], flat[1], scratch, acc, s)
    final = np.ascontiguousarray(xy[:, xy.shape[1] - 1])
    score_end(w, final, acc, out, s)


@njit(**FAST)
def env_step(xy, heading, actions, w, s, acc, value, obs):
    """One step of E environments of the world ``w`` in one call, in place: move (hooks ``move``, ``tick``), score
    (``score_step`` where ``stepwise``, then ``score_end``: the running value (E,) in ``value``), observe (``sense``)
    into obs (E, N, D). xy (E, N, 2), heading (E, N), actions (E, N, 2) in the kernel's precision; the state ``s``
    (:func:`state_of`) and ``acc`` (:func:`env_start`) are carried from step to step of the episode."""
    n_ep, n = heading.shape
    ne = n * n_ep
    state = _moved(xy, heading, actions, w, s)
    x, y, sin_h, cos_h = state[0], state[1], state[3], state[4]   # sin_h, cos_h follow the new heading
    pos = np.empty((n_ep, n, 2))                          # the reward reads float64
    if stepwise(w):
        score_step(w, x, y, pos, acc, s)
    from_flat(x, pos[:, :, 0])
    from_flat(y, pos[:, :, 1])
    score_end(w, pos, acc, value, s)
    flat = np.empty(w.obs_dim * ne, dtype=xy.dtype)
    sense(x, y, sin_h, cos_h, n, w, s, flat)
    for k in range(w.obs_dim):
        from_flat(flat[k * ne:(k + 1) * ne], obs[:, :, k])


@njit(cache=True)
def env_start(w, n_ep):
    """The reward state of E environments before their first :func:`env_step` (the hook ``score_start``)."""
    return score_start(w, n_ep)


@njit(cache=True)
def trial(hook, x, y, heading, sin_h, cos_h, a0, a1, n, w, s, obs, xy, acc, returns):
    """One call of the world's hook number ``hook`` (``trial.check_state``'s trial run, which checks the state
    ``s`` between calls): 0 ``begin``, 1 ``sense``, 2 ``move``, 3 ``tick``, 4 ``stepwise``, 5 ``score_step``,
    6 ``score_end``, on the flat layout; returns what ``sense`` or ``stepwise`` return (False for the others)."""
    if hook == 0:
        begin(x, y, n, w, s)
    elif hook == 1:
        return sense(x, y, sin_h, cos_h, n, w, s, obs)
    elif hook == 2:
        move(x, y, heading, sin_h, cos_h, a0, a1, w, s)
    elif hook == 3:
        tick(x, y, n, w, s)
    elif hook == 4:
        return stepwise(w)
    elif hook == 5:
        score_step(w, x, y, xy, acc, s)
    else:
        score_end(w, xy, acc, returns, s)
    return False


@njit(nogil=True, **FAST)
def evaluate(genomes, xy0, heading0, fields, returns, final_xy):
    """(score, sane) of one team genomes (N, G) float64: :func:`rollout` (returns (E,), final_xy as there), then the
    mean of the returns in numpy's summation order (``reward.score``); ``sane``: every weight is a finite number of
    sane size (``lanes.sane_teams``: the caller warns of a team that scored 0 without). ``fields`` is the world's
    :class:`KernelWorld` as a plain tuple (numba types a plain tuple argument 3x faster than the record: 0.6 against
    2 us a call). The genomes go to the kernel's precision (that of xy0) here."""
    sane = np.empty(1, dtype=np.bool_)
    sane_teams(genomes, heading0.shape[1], sane)
    no_xy, no_heading = np.empty((0, 1, 1, 2)), np.empty((0, 1, 1))
    rollout(in_precision(genomes, xy0), xy0, heading0, KernelWorld(*fields), returns, no_xy, no_heading, final_xy)
    return score(returns), sane[0]


@njit(nogil=True, **FAST)
def evaluate_many(teams, xy0, heading0, fields, returns, scores, sane, final_xy, per_pass):
    """:func:`evaluate` of B teams (B*N, G) float64 (team b's rovers in rows ``b*N ..``) on the same initial
    conditions, ``per_pass`` teams side by side in one rollout's lanes (:mod:`~rovermarl.env.kernel.lanes`): scores
    (B,), sane (B,), returns (B*E,) (team b's from ``b*E``), final_xy (B*E, N, 2) unless its first axis is
    zero-sized. Each score is the bits the team's own :func:`evaluate` gives, whichever teams share its pass, so
    threads may each run this call on a chunk of a population (the GIL is released: ``prepared.score_teams``)."""
    n_ep, n = heading0.shape
    b_all = scores.shape[0]
    w = KernelWorld(*fields)
    no_xy, no_heading = np.empty((0, 1, 1, 2)), np.empty((0, 1, 1))
    for b0 in range(0, b_all, per_pass):
        b1 = min(b0 + per_pass, b_all)
        sane_teams(teams[b0 * n:b1 * n], n, sane[b0:b1])
        final = final_xy[b0 * n_ep:b1 * n_ep] if final_xy.shape[0] else final_xy
        rollout(in_precision(teams[b0 * n:b1 * n], xy0), xy0, heading0, w, returns[b0 * n_ep:b1 * n_ep], no_xy,
                no_heading, final)
        for b in range(b0, b1):
            scores[b] = score(returns[b * n_ep:(b + 1) * n_ep])
