"""What a user calls, against the compiled rollout it wraps, in one process: ``World.evaluate`` (initial conditions
prepared once, ``World.prepare``, and plain), ``World.evaluate_many`` at B = 1, 16, 64 teams on one core and B = 64
on two, in float64 and float32; and ``World.evaluate`` against 4c4ae3c's (its kernel, ``kernel_4c4ae3c.py``, with its
``World.evaluate`` wrapper as it was). Prints one JSON line.

    python benchmarks/api.py                 # about 2 minutes once compiled; --quick: about 20 s, no 4c4ae3c
    python benchmarks/api.py --quick --guard 1.25    # .ci/run: exit 1 if World.evaluate / rollout > 1.25
    python benchmarks/api.py --two-cores-only --rounds 3     # the two-core part alone, 3 rounds in one process

The single-core figures run on one pinned core (``--core``, default the last this process may use; the process
pins itself), the two-core ones on two. Within each repeat the timed calls run in ``--chunks`` chunks in rotating
order, so that machine noise hits them alike; each ratio is the median over repeats of the per-repeat ratio of
times (below 1: faster than the rollout). Single-core times are process CPU time; the two-core ones wall time
(threads), also for their one-core reference, so ``two_cores_over_one`` is a rate ratio in wall time;
``two_processes_over_one`` is the same ratio for two processes, one a core, with no thread pool or GIL between
them: the most two cores give this work here, against which the threads' figure reads. ``two_cores_over_one_busy``
and ``_niced_busy``: the same ratio while another process keeps a core busy (``while True: pass``; then under
``nice -n 10``): more threads must never be slower than one (issue 52's targets: 1.6x idle, never below 0.95x
busy). The load average is printed: on a shared machine the two-core figures are what the other processes leave.

Teams (``setup=duo``, its 16 initial conditions of run 0): the first of 256 random teams (genomes uniform in
[-2, 2]) that scores 0 (``zero``; most random and early teams do) and the first that scores above 0 (``scoring``);
evaluate_many scores the first B of the 256. Per-team times of evaluate_many are compared with the rollout of
the zero-scoring team (the same work). ``steps_share_of_rollout``: the part of that rollout that its steps take,
from the same rollout with twice the steps (``t(2T) / t(T) - 1``); the rest is the call's fixed cost, all that a
batch of teams can share.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import time

import numpy as np

from rovermarl import make_world


def timed(f, n: int, clock) -> float:
    t = clock()
    for _ in range(n):
        f()
    return clock() - t


def alternate(fns: dict, counts: dict, repeats: int, chunks: int, clock=time.process_time) -> dict:
    """Seconds per call of each function (R,), each repeat's calls split in ``chunks`` chunks in rotating order."""
    names = list(fns)
    for name in names:
        fns[name]()                                                     # warm: compiled, caches filled
    out = {name: [] for name in names}
    for r in range(repeats):
        total = dict.fromkeys(names, 0.0)
        for c in range(chunks):
            shift = (r + c) % len(names)
            for name in names[shift:] + names[:shift]:
                total[name] += timed(fns[name], max(1, counts[name] // chunks), clock)
        for name in names:
            out[name].append(total[name] / (max(1, counts[name] // chunks) * chunks))
    return {name: np.array(v) for name, v in out.items()}


def ratio(times: dict, a: str, b: str) -> float:
    """Median over repeats of time(a) / time(b)."""
    return round(float(np.median(times[a] / times[b])), 4)


def us(times: dict, name: str) -> float:
    return round(float(np.min(times[name])) * 1e6, 2)


def teams_of(world, ic) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """256 random teams (B, N, P), the first zero-scoring and the first scoring one."""
    teams = np.random.default_rng(0).uniform(-2, 2, (256, world.n_rovers, world.n_params))
    scores = world.evaluate_many(teams, ic, workers=1)
    if not (scores == 0).any() or not (scores > 0).any():
        raise RuntimeError("no zero-scoring or no scoring team among 256 random ones: choose another --setup")
    return teams, teams[np.flatnonzero(scores == 0)[0]], teams[np.flatnonzero(scores > 0)[0]]


def rollout_call(world, genomes, p):
    """The compiled rollout of one team, called as ``World.kernel_args`` hands it (genomes in ``env.dtype``)."""
    args = (np.ascontiguousarray(genomes, world._float), *world.kernel_args(p), np.empty(p.episodes),
            np.empty((0, 1, 1, 2)), np.empty((0, 1, 1)), np.empty((0, 1, 2)))
    return lambda: world.compiled.rollout(*args)


def old_evaluate(world):
    """4c4ae3c's ``World.evaluate`` (its checks, its kernel ``kernel_4c4ae3c.rollout``, its score; float64), and its
    bare kernel call."""
    import kernel_4c4ae3c as old  # same folder
    task = world.task
    consts = (world.poi_xy, task.sensor_type, task.coupling, task.value, world.steps, world.policy.hidden,
              float(world.sensor_range), float(world.obs_radius), float(world.v_max), world.w_max)
    no = (np.empty((0, 1, 1, 2)), np.empty((0, 1, 1)), np.empty((0, 1, 2)))

    def bare(genomes, ic):
        out = np.empty(ic[1].shape[0])
        args = (np.ascontiguousarray(genomes), np.ascontiguousarray(ic[0]), np.ascontiguousarray(ic[1]), *consts, out,
                *no)
        return lambda: old.rollout(*args)

    def evaluate(genomes, ic):
        genomes = np.ascontiguousarray(genomes, dtype=np.float64)
        if genomes.shape != (world.n_rovers, world.n_params):
            raise ValueError("genomes")
        xy, heading = (np.ascontiguousarray(a, dtype=np.float64) for a in ic[:2])
        if xy.shape[-2:] != (world.n_rovers, 2) or heading.shape != xy.shape[:-1]:
            raise ValueError("ic")
        out = np.empty(heading.shape[0])
        old.rollout(genomes, xy, heading, *consts, out, *no)
        return float(out.sum()) / out.shape[0]
    return evaluate, bare


def one_core(dtype: str, a, old) -> dict:
    world = make_world(a.setup, dtype=dtype)
    ic = world.run_ic(0)
    p = world.prepare(ic)
    teams, zero, scoring = teams_of(world, p)
    fns = {"rollout_zero": rollout_call(world, zero, p), "rollout_scoring": rollout_call(world, scoring, p),
           "evaluate_zero": lambda: world.evaluate(zero, p), "evaluate_scoring": lambda: world.evaluate(scoring, p),
           "evaluate_plain_ic": lambda: world.evaluate(zero, ic)}
    for b in (1, 16, 64):
        fns[f"many_{b}"] = lambda b=b: world.evaluate_many(teams[:b], p, workers=1)
    longer = make_world(a.setup, dtype=dtype, steps=2 * world.steps)     # the same episodes, twice the steps
    fns["rollout_zero_2t"] = rollout_call(longer, zero, longer.prepare(ic))
    if old is not None:
        fns["old_evaluate"] = lambda: old[0](zero, ic)
        fns["old_kernel"] = old[1](zero, ic)
    counts = {name: a.evals // (int(name.split("_")[1]) if name.startswith("many_") else 1) for name in fns}
    t = alternate(fns, counts, a.repeats, a.chunks)
    for b in (1, 16, 64):
        t[f"many_{b}"] = t[f"many_{b}"] / b                              # per team
    out = {"rollout_us": {"zero": us(t, "rollout_zero"), "scoring": us(t, "rollout_scoring")},
           "evaluate_us": {"zero": us(t, "evaluate_zero"), "scoring": us(t, "evaluate_scoring")},
           "evaluate_over_rollout": {"zero": ratio(t, "evaluate_zero", "rollout_zero"),
                                     "scoring": ratio(t, "evaluate_scoring", "rollout_scoring")},
           "evaluate_plain_ic_over_rollout": ratio(t, "evaluate_plain_ic", "rollout_zero"),
           "many_us_per_team": {b: us(t, f"many_{b}") for b in (1, 16, 64)},
           "many_per_team_over_rollout": {b: ratio(t, f"many_{b}", "rollout_zero") for b in (1, 16, 64)},
           # the steps' share of the rollout: t(2T)/t(T) - 1 = 1 - fixed/t(T). A batch shares only the fixed part,
           # so its per-team time over the rollout stays above this unless a step gets cheaper per team in it
           "steps_share_of_rollout": round(float(np.median(t["rollout_zero_2t"] / t["rollout_zero"])) - 1, 4)}
    if old is not None:
        out["old_evaluate_us"], out["old_kernel_us"] = us(t, "old_evaluate"), us(t, "old_kernel")
        out["evaluate_speedup_over_4c4ae3c"] = ratio(t, "old_evaluate", "evaluate_zero")          # the speed check
        out["evaluate_speedup_over_4c4ae3c_kernel"] = ratio(t, "old_kernel", "evaluate_zero")     # its bare kernel
    return out


BUSY = {"busy": [], "niced_busy": ["nice", "-n", "10"]}    # another process keeping a core busy, and the same niced


@contextlib.contextmanager
def busy(nice: list[str]):
    """A process spinning in Python on one core (under ``nice`` if given) while the block runs."""
    proc = subprocess.Popen([*nice, sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.5)
        yield
    finally:
        proc.kill()
        proc.wait()


def two_cores(dtype: str, a) -> dict:
    """B = 64 on one thread and on two (wall time, both on the two cores this process is given): as the machine is,
    then with another process busy on a core (:data:`BUSY`: not niced, niced)."""
    world = make_world(a.setup, dtype=dtype)
    p = world.prepare(world.run_ic(0))
    teams = np.random.default_rng(0).uniform(-2, 2, (64, world.n_rovers, world.n_params))
    fns = {"one": lambda: world.evaluate_many(teams, p, workers=1),
           "two": lambda: world.evaluate_many(teams, p, workers=2)}
    n = max(2, a.evals // 64)
    t = alternate(fns, {"one": n, "two": n}, a.repeats, a.chunks, clock=time.perf_counter)
    out = {"many_64_us_per_team": {"one_thread": round(float(np.min(t["one"])) / 64 * 1e6, 2),
                                   "two_threads": round(float(np.min(t["two"])) / 64 * 1e6, 2)},
           "two_cores_over_one": round(float(np.median(t["one"] / t["two"])), 4),
           "two_processes_over_one": two_processes(world, p, teams, n, a.repeats)}
    for name, nice in BUSY.items():
        with busy(nice):
            t = alternate(fns, {"one": n, "two": n}, a.repeats, a.chunks, clock=time.perf_counter)
        out[f"two_cores_over_one_{name}"] = round(float(np.median(t["one"] / t["two"])), 4)
    return out


def two_processes(world, p, teams, n: int, repeats: int) -> float:
    """The machine's own ceiling for :func:`two_cores`: the rate of two processes, one pinned to each core, each
    making the same ``n`` one-thread ``evaluate_many`` calls at once, over the rate of one such process alone (no
    GIL, no thread pool between them: what the cores give two copies of this work). Median over ``repeats`` of
    alternated alone/pair rounds (forked, so nothing compiles again)."""
    import multiprocessing as mp

    cores = sorted(os.sched_getaffinity(0))[:2]

    def work(core, conn, start):
        os.sched_setaffinity(0, {core})
        world.evaluate_many(teams, p, workers=1)                       # warm on this core
        start.wait()
        t = time.perf_counter()
        for _ in range(n):
            world.evaluate_many(teams, p, workers=1)
        conn.send(time.perf_counter() - t)

    def round_of(on) -> list:
        ctx = mp.get_context("fork")
        start, pipes = ctx.Barrier(len(on)), [ctx.Pipe(duplex=False) for _ in on]
        procs = [ctx.Process(target=work, args=(c, w, start)) for c, (_, w) in zip(on, pipes, strict=True)]
        for proc in procs:
            proc.start()
        times = [r.recv() for r, _ in pipes]
        for proc in procs:
            proc.join()
        return times

    ratios = []
    for _ in range(repeats):
        alone, pair = round_of(cores[:1])[0], round_of(cores)
        ratios.append(alone * sum(1 / t for t in pair))               # rate of the pair / rate alone
    return round(float(np.median(ratios)), 4)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="duo")
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--evals", type=int, default=2000, help="single-team calls per repeat and function")
    p.add_argument("--chunks", type=int, default=10)
    p.add_argument("--core", type=int, default=None, help="the core of the single-core part (default: the last)")
    p.add_argument("--quick", action="store_true", help="3 repeats of 500 calls, no 4c4ae3c comparison")
    p.add_argument("--two-cores-only", action="store_true", help="only the two-core part (B = 64), --rounds times")
    p.add_argument("--rounds", type=int, default=1, help="with --two-cores-only: rounds in this one process")
    p.add_argument("--guard", type=float, default=None,
                   help="exit 1 if World.evaluate / rollout (prepared ic) is above this in either dtype or team")
    a = p.parse_args()
    if a.quick:
        a.repeats, a.evals, a.chunks = 3, 500, 5
    cores = sorted(os.sched_getaffinity(0))
    load_start = os.getloadavg()
    if a.two_cores_only:
        if a.guard is not None or len(cores) < 2:
            p.error("--two-cores-only needs two CPUs and takes no --guard")
        rounds = [{dtype: two_cores(dtype, a) for dtype in ("float64", "float32")} for _ in range(a.rounds)]
        print(json.dumps({"benchmark": "api", "setup": a.setup, "two_cores_rounds": rounds,
                          "loadavg_1m_start": round(load_start[0], 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
                          "cpus": len(cores)}))
        return
    old = None
    if not a.quick:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        old = old_evaluate(make_world(a.setup))
    os.sched_setaffinity(0, {cores[-1] if a.core is None else a.core})
    single = {dtype: one_core(dtype, a, old) for dtype in ("float64", "float32")}
    os.sched_setaffinity(0, set(cores))
    double = {dtype: two_cores(dtype, a) for dtype in ("float64", "float32")} if len(cores) >= 2 else {}
    out = {"benchmark": "api", "setup": a.setup, "quick": a.quick, "repeats": a.repeats, "evals": a.evals,
           "one_core": single, "two_cores": double,
           "loadavg_1m_start": round(load_start[0], 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
           "cpus": len(cores), "python": sys.version.split()[0]}
    print(json.dumps(out))
    if a.guard is not None:
        worst = max(r for d in single.values() for r in d["evaluate_over_rollout"].values())
        if worst > a.guard:
            print(f"benchmarks/api.py: World.evaluate takes {worst}x the compiled rollout, above --guard {a.guard}",
                  file=sys.stderr)
            sys.exit(1)


if __name__ == "__main__":
    main()
