"""Evaluation at the kernel's speed: initial conditions prepared once (:class:`Prepared`), teams scored in the
kernel's lanes and on every core (:func:`score_teams`).

``World.prepare(ic)`` checks the initial conditions and puts them in the kernel's precision once; ``World.evaluate``,
``returns``, ``evaluate_many``, ``rollout`` and ``kernel_args`` take the :class:`Prepared` wherever they take ``ic``,
and then check and convert only the genomes per call. Plain initial conditions still work: they are prepared on
every call (a few microseconds). ``World.evaluate_many`` lays several teams' episodes side by side in one rollout's
lanes (:mod:`rovermarl.env.kernel.lanes`) and splits a population of at least ``2 * MIN_TEAMS`` teams into
contiguous chunks that shrink as they go (:func:`guided`, OpenMP's guided schedule), in a ``queue.SimpleQueue``:
the calling thread and ``threads - 1`` tasks on this process's one ``concurrent.futures.ThreadPoolExecutor`` each
take the next chunk until none is left, and the caller cancels a task that has not started (``Future.cancel``), so
that a thread held up on a busy machine delays one chunk at most, a small one once the population is under way.
Each chunk is one call of the compiled ``evaluate_many`` (the GIL released); each score is the bits
``World.evaluate`` gives, whichever chunk and pass it is in.
"""

from __future__ import annotations

import os
import queue
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from rovermarl import jit

PASS_LANES = 256        # episodes of all teams in one pass of the batched rollout (16 teams of 16 episodes)
MIN_TEAMS = 8           # a thread a MIN_TEAMS teams at most: fewer a thread cost more to hand over than they save
MIN_CHUNK = 4           # teams a chunk at least (the last takes what is left): a call costs about 15 us (float64)
NO_FINAL = np.empty((0, 1, 2))          # final_xy when none is kept (no first axis)
_F64 = np.dtype(np.float64)
_POOL: dict[int, tuple[int, ThreadPoolExecutor]] = {}   # pid: (threads, this process's pool); a forked child
                                                         # makes its own
_POOL_LOCK = threading.Lock()


class Rollout(NamedTuple):
    """Trajectories of E episodes: xy (E, T+1, N, 2), heading (E, T+1, N), returns (E,), and the episodes' layout
    (E, K) (``InitialConditions.layout``; K = 0 for the paper's world), so that counterfactual teams can be
    re-scored on each episode's own POIs (``World.episode_return``)."""

    xy: np.ndarray
    heading: np.ndarray
    returns: np.ndarray
    layout: np.ndarray


class Prepared(NamedTuple):
    """Initial conditions as the kernel reads them (``World.prepare``): ``ic`` the checked initial conditions
    (float64), ``xy`` (E, N, 2) and ``heading`` (E, N) in ``env.dtype``, C-ordered, writeable copies (later changes
    to the arrays passed in are not seen), ``kernel`` the world's :class:`~rovermarl.env.kernel.KernelWorld` with
    their layout, ``fields`` the same as a plain tuple (numba takes it faster), ``world`` the world that prepared them
    (another world prepares ``ic`` again)."""

    ic: tuple
    xy: np.ndarray
    heading: np.ndarray
    kernel: tuple
    fields: tuple
    world: object

    @property
    def episodes(self) -> int:
        return self.heading.shape[0]


def genomes_in(genomes, shape: tuple[int, ...], what: str) -> np.ndarray:
    """genomes as the kernel takes them: float64, C-ordered and writeable (numba compiles again for a read-only
    array, as Ray delivers it), of ``shape`` (a copy only where needed)."""
    if type(genomes) is np.ndarray and genomes.dtype is _F64 and genomes.shape == shape:
        flags = genomes.flags
        if flags.c_contiguous and flags.writeable:
            return genomes                                  # the common case: 4 checks
    genomes = np.ascontiguousarray(genomes, dtype=np.float64)
    if genomes.shape != shape:
        raise ValueError(f"{what} must have shape ({', '.join(map(str, shape))}), got {genomes.shape}")
    return genomes if genomes.flags.writeable else genomes.copy()


def final_in(final_xy, shape: tuple[int, ...]) -> np.ndarray:
    """``final_xy`` as the kernel writes into it: a writeable C-ordered float64 array of ``shape``, else a one-line
    ValueError (a copy in another dtype would not reach the caller; numba would compile again for another layout)."""
    if isinstance(final_xy, np.ndarray) and final_xy.dtype is _F64 and final_xy.shape == shape \
            and final_xy.flags.c_contiguous and final_xy.flags.writeable:
        return final_xy
    got = (f"{'read-only ' if not final_xy.flags.writeable else ''}"
           f"{'' if final_xy.flags.c_contiguous else 'strided '}{final_xy.dtype} {final_xy.shape}"
           if isinstance(final_xy, np.ndarray) else type(final_xy).__name__)
    raise ValueError(f"final_xy must be a writeable C-ordered float64 array of shape {shape}, got {got}")


def workers_in(workers) -> int | None:
    """``workers`` of ``World.evaluate_many``: None or an integer >= 1, else a one-line ValueError."""
    if workers is None or (isinstance(workers, (int, np.integer)) and not isinstance(workers, bool) and workers >= 1):
        return workers
    raise ValueError(f"workers must be None or an integer >= 1, got {workers!r}")


def score_teams(world, teams: np.ndarray, p: Prepared, final_xy=None, workers: int | None = None):
    """Scores (B,), returns (B*E,) of teams (B*N, P) float64 (:func:`genomes_in`) on ``p``; final_xy (B*E, N, 2) if
    given. ``workers``: threads at most (None: the CPUs this process may run on, :func:`cpus`; never more), and at
    most one a :data:`MIN_TEAMS` teams, taking :func:`guided` chunks. No team: no call of the kernel."""
    n, b, e = world.n_rovers, teams.shape[0] // world.n_rovers, p.episodes
    scores, returns, sane = np.empty(b), np.empty(b * e), np.empty(b, dtype=np.bool_)
    if not b:
        return scores, returns
    final = NO_FINAL if final_xy is None else final_xy
    per_pass = max(1, PASS_LANES // e)
    run = world.compiled.evaluate_many
    jit.say_if_cold(run, (teams, p.xy, p.heading, p.fields, returns, scores, sane, final, per_pass),
                    "the world's rollout")
    threads = max(1, min(cpus() if workers is None else workers, cpus(), b // MIN_TEAMS))
    cuts = guided(b, threads)                                    # contiguous chunks [cuts[k], cuts[k+1])
    parts = len(cuts) - 1

    def chunk(k: int) -> tuple:
        b0, b1 = cuts[k], cuts[k + 1]
        return (teams[b0 * n:b1 * n], p.xy, p.heading, p.fields, returns[b0 * e:b1 * e], scores[b0:b1], sane[b0:b1],
                final[b0 * e:b1 * e] if final.shape[0] else final, per_pass)

    todo = queue.SimpleQueue()                                   # the chunks not yet taken, in order
    for k in range(parts):
        todo.put(k)

    def work() -> None:                                          # one thread's share: chunks until none is left
        while True:
            try:
                k = todo.get_nowait()
            except queue.Empty:
                return
            run(*chunk(k))

    others = [_pool(threads - 1).submit(work) for _ in range(threads - 1)]
    try:
        work()
    finally:
        for f in others:
            if not f.cancel():                                   # started: wait for it (raises its error); one
                f.result()                                       # that has not (a busy machine) is not waited for
    if not sane.all():
        warn_insane(sane, returns.reshape(b, e))
    return scores, returns


def guided(b: int, threads: int) -> list[int]:
    """Chunk bounds (parts + 1,) over b teams: each chunk a ``2 * threads``-th of the teams left (rounded up), at
    least :data:`MIN_CHUNK`; one chunk on one thread. The small last chunks leave little for the caller to wait on
    when a thread is held up (docs/PERFORMANCE.md, 2026-12-08: 64 teams on 2 cores, side by side with even chunks of
    16, two threads over one 1.86-1.92 against 1.73-1.79 idle, 1.06-1.30 against 0.96-1.06 with a core busy)."""
    cuts = [0]
    while cuts[-1] < b:
        left = b - cuts[-1]
        cuts.append(b if threads == 1 else cuts[-1] + min(left, max(MIN_CHUNK, -(-left // (2 * threads)))))
    return cuts


def warn_insane(sane: np.ndarray, returns: np.ndarray) -> None:
    """One warning naming the first team (B,) whose genomes are not finite numbers of sane size (|w| < 1e150:
    beyond that the MLP's sums overflow) and whose returns (B, E) are all 0: the rollout plays such genomes as rovers
    that stop. A team that scored anyway is not warned about."""
    bad = np.flatnonzero(~sane & ~returns.any(axis=1))
    if bad.size:
        warnings.warn(f"team {int(bad[0])}'s genomes hold nan, inf or magnitudes >= 1e150: the rollout plays them as "
                      "non-finite actions, which score 0", RuntimeWarning, stacklevel=4)


def cpus() -> int:
    """The CPUs this process may run on (its affinity, e.g. under taskset)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:                               # not on Linux
        return os.cpu_count() or 1


def _pool(threads: int) -> ThreadPoolExecutor:
    """This process's thread pool, made at first use with at least ``threads`` threads (made as they are needed;
    a call runs ``threads`` tasks on it at most)."""
    with _POOL_LOCK:
        size, pool = _POOL.get(os.getpid(), (0, None))
        if size < threads:                               # e.g. the process's CPUs grew since
            if pool is not None:
                pool.shutdown(wait=False)                # its threads end once their work is done
            _POOL.clear()
            _POOL[os.getpid()] = threads, (pool := ThreadPoolExecutor(threads, thread_name_prefix="rovermarl"))
        return pool
