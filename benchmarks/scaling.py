"""Ray throughput: seed-parallel runs with 1..W workers, and the initial-condition-shard trade-off.

Prints one JSON line and writes a plot (``--plot``, default ``docs/figures/scaling.png``).

    python benchmarks/scaling.py [--cpus 2] [--generations 20000] [--seeds 4] [--repeats 3]

- ``seed_parallel``: team evaluations per second of whole runs (``run_records``, default recording) with
  ``parallel.workers`` = 1..cpus; measured alternately, median of ``--repeats``.
- ``bare_processes``: the same loop in 1..cpus plain processes without Ray, for the hardware's own scaling;
- ``ic_shards``: time per generation of one run evaluated locally vs with its episodes split over S actors,
  for worlds made heavier by ``env.steps`` and ``env.episodes``; ``break_even_agent_steps`` is the lightest
  measured world (agent-steps per team evaluation) where sharding is faster than local evaluation.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from multiprocessing import get_context

import ray
from omegaconf import OmegaConf

from rovermarl.config import compose_config
from rovermarl.parallel import run_records
from rovermarl.parallel.ray_backend import release_pool
from rovermarl.parallel.shards import ShardActor, ShardedEvaluation
from rovermarl.record.checkpoint import RunRecord
from rovermarl.runner.chunk import Run, advance, parts, to_plain


def seed_parallel_rate(workers: int, generations: int, seeds: int) -> float:
    """Team evaluations per second of ``seeds`` whole runs on ``workers`` Ray workers."""
    cfg = compose_config(f"parallel.workers={workers}", f"generations={generations}", f"seeds={seeds}")
    job = to_plain(cfg)
    records = [RunRecord(s, generations, parts(job).algorithm.series) for s in range(seeds)]
    t = time.perf_counter()
    run_records(cfg, job, records, lambda rec, n: None, advance)
    return seeds * (generations + 1) / (time.perf_counter() - t)


def _bare(generations: int) -> float:
    """One bare process: seconds for ``generations`` of one run's loop (after a warm-up)."""
    cfg = OmegaConf.to_container(compose_config(f"generations={generations + 100}"), resolve=True)
    run = Run(cfg, seed=os.getpid())
    run.advance(100)
    t = time.perf_counter()
    run.advance(generations)
    return time.perf_counter() - t


def bare_rate(procs: int, generations: int) -> float:
    """Team evaluations per second of ``procs`` plain processes without Ray (the hardware's own scaling)."""
    with ProcessPoolExecutor(procs, mp_context=get_context("spawn")) as pool:
        list(pool.map(_bare, [200] * procs))                       # start and warm up every process
        times = list(pool.map(_bare, [generations] * procs))
    return procs * generations / max(times)


def per_generation(run: Run, n: int) -> float:
    """Seconds per generation of ``run.advance`` (after a short warm-up)."""
    run.advance(5)
    t = time.perf_counter()
    run.advance(n)
    return (time.perf_counter() - t) / n


def shard_costs(shards: int, worlds: list[tuple[int, int]], budget_s: float) -> list[dict]:
    """Local vs sharded seconds per generation for each (steps, episodes) world."""
    out = []
    for steps, episodes in worlds:
        cfg = OmegaConf.to_container(compose_config(f"env.steps={steps}", f"env.episodes={episodes}",
                                                    "generations=100000"), resolve=True)
        local = Run(cfg, seed=0)
        t_local = per_generation(local, 3)
        n = max(5, min(2000, int(budget_s / t_local)))
        t_local = per_generation(local, n)
        release_pool()                                             # the seed-parallel actors hold the CPUs
        actors = [ShardActor.remote(cfg) for _ in range(shards)]
        sharded = Run(cfg, seed=0, evaluation=partial(ShardedEvaluation, actors))
        t_shard = per_generation(sharded, max(5, min(2000, int(budget_s / max(t_local, 1e-3)))))
        for a in actors:
            ray.kill(a)
        agent_steps = steps * episodes * cfg["env"]["n_rovers"]
        out.append({"steps": steps, "episodes": episodes, "agent_steps_per_eval": agent_steps,
                    "local_ms_per_gen": round(t_local * 1e3, 4), "sharded_ms_per_gen": round(t_shard * 1e3, 4),
                    "shard_over_local": round(t_shard / t_local, 3)})
    return out


def plot(result: dict, path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    sp = result["seed_parallel"]
    a.bar([str(w) for w in sp], [sp[w]["team_evals_per_s"] for w in sp], color="C0")
    a.set(xlabel="Ray workers", ylabel="team evaluations / s", title="seed-parallel runs")
    rows = result["ic_shards"]["worlds"]
    x = [r["agent_steps_per_eval"] for r in rows]
    b.loglog(x, [r["local_ms_per_gen"] for r in rows], "o-", label="local")
    b.loglog(x, [r["sharded_ms_per_gen"] for r in rows], "s-", label=f"{result['ic_shards']['shards']} IC shards")
    b.set(xlabel="agent-steps per team evaluation", ylabel="ms per generation", title="IC shards vs local")
    b.axvline(960, color="grey", ls=":", lw=1)
    b.text(960, b.get_ylim()[1], " paper world", va="top", fontsize=8, color="grey")
    b.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cpus", type=int, default=2)
    p.add_argument("--generations", type=int, default=20000)
    p.add_argument("--seeds", type=int, default=4)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--shards", type=int, default=2)
    p.add_argument("--budget", type=float, default=2.0, help="seconds per shard measurement")
    p.add_argument("--plot", default=os.path.join(os.path.dirname(__file__), "..", "docs", "figures", "scaling.png"))
    a = p.parse_args()

    load0 = os.getloadavg()[0]
    ray.init(num_cpus=a.cpus, include_dashboard=False, log_to_driver=False)
    seed_parallel_rate(a.cpus, 200, a.cpus)                        # warm up workers and the numba cache
    rates = {w: [] for w in range(1, a.cpus + 1)}
    for _ in range(a.repeats):                                     # alternate so machine noise hits all alike
        for w in rates:
            rates[w].append(seed_parallel_rate(w, a.generations, a.seeds))
    seed_parallel = {w: {"team_evals_per_s": round(statistics.median(r), 1), "runs": [round(x, 1) for x in r]}
                     for w, r in rates.items()}
    bare = {w: [] for w in rates}
    for _ in range(a.repeats):
        for w in bare:
            bare[w].append(bare_rate(w, a.generations // 2))
    bare = {w: round(statistics.median(r), 1) for w, r in bare.items()}
    worlds = [(15, 16), (60, 16), (15, 256), (240, 16), (60, 256), (120, 256), (240, 256)]
    rows = shard_costs(a.shards, worlds, a.budget)
    ray.shutdown()
    faster = [r["agent_steps_per_eval"] for r in rows if r["shard_over_local"] < 1.0]
    result = {
        "benchmark": "scaling", "cpus": a.cpus, "generations": a.generations, "seeds": a.seeds,
        "seed_parallel": seed_parallel,
        "speedup_max_workers": round(seed_parallel[a.cpus]["team_evals_per_s"] / seed_parallel[1]["team_evals_per_s"],
                                     3),
        "bare_processes_team_evals_per_s": bare,
        "bare_speedup_max_procs": round(bare[a.cpus] / bare[1], 3),
        "ic_shards": {"shards": a.shards, "worlds": rows, "break_even_agent_steps": min(faster) if faster else None},
        "loadavg_1m_start": round(load0, 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
    }
    plot(result, a.plot)
    result["plot"] = a.plot
    print(json.dumps(result))


if __name__ == "__main__":
    main()
