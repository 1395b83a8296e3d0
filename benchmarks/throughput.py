"""Single-core throughput of the default world: the team-evaluation kernel alone and the full
CC-(1+1)-ES generation loop. Prints one JSON line.

    python benchmarks/throughput.py [--setup solo] [--repeats 5] [--evals 3000]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import numpy as np
from omegaconf import OmegaConf

from rovermarl import make_world
from rovermarl.config import compose_config
from rovermarl.evolution import Run, evolve


def kernel_rate(world, n: int) -> float:
    """Team evaluations per second of ``world.evaluate`` on a fixed random team."""
    ic = world.initial_conditions(seed=0)
    genomes = np.random.default_rng(0).uniform(-2, 2, (world.n_rovers, world.n_params))
    t = time.perf_counter()
    for _ in range(n):
        world.evaluate(genomes, ic)
    return n / (time.perf_counter() - t)


def loop_rate(cfg: dict, n: int) -> float:
    """Generations (= team evaluations) per second of the full loop: choose, mutate, evaluate, select, record."""
    run = Run({**cfg, "generations": n}, seed=0)
    t = time.perf_counter()
    evolve(run, n)
    return n / (time.perf_counter() - t)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="solo")
    p.add_argument("--k", default="1")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--evals", type=int, default=3000, help="team evaluations per repeat")
    a = p.parse_args()

    cfg = OmegaConf.to_container(compose_config(f"setup={a.setup}", f"k={a.k}"), resolve=True)
    world = make_world(a.setup)
    kernel_rate(world, 50)                                   # JIT / cache warm-up
    loop_rate(cfg, 50)
    kernel, loop = [], []
    for _ in range(a.repeats):                               # alternate so machine noise hits both alike
        kernel.append(kernel_rate(world, a.evals))
        loop.append(loop_rate(cfg, a.evals))
    k_med, l_med = statistics.median(kernel), statistics.median(loop)
    agent_steps = world.episodes * world.steps * world.n_rovers
    print(json.dumps({
        "benchmark": "throughput", "setup": a.setup, "k": a.k, "repeats": a.repeats, "evals_per_repeat": a.evals,
        "team_evals_per_s": round(k_med, 1),
        "agent_steps_per_s": round(k_med * agent_steps, 1),
        "loop_team_evals_per_s": round(l_med, 1),
        "loop_over_kernel": round(l_med / k_med, 3),
        "agent_steps_per_team_eval": agent_steps,
        "kernel_runs": [round(x, 1) for x in kernel], "loop_runs": [round(x, 1) for x in loop],
        "loadavg_1m": round(os.getloadavg()[0], 2), "cpus": os.cpu_count(), "python": platform.python_version(),
    }))


if __name__ == "__main__":
    main()
