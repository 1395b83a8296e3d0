"""Single-core throughput of the default world: the team-evaluation kernel alone, the full
CC-(1+1)-ES generation loop, and a plain numpy rollout (benchmarks/numpy_rollout.py) as baseline.
Prints one JSON line.

    python benchmarks/throughput.py [--setup solo] [--repeats 5] [--evals 3000] [--numpy-evals 150]

The three are measured alternately in each repeat, so that machine noise hits them alike; ratios are
medians of the per-repeat ratios. The numpy rollout's per-episode returns are checked against the
kernel's on ``--check-teams`` random teams (``numpy_return_mismatches`` counts differing episodes).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import numpy as np
from numpy_rollout import rollout as numpy_rollout  # same folder
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


def numpy_rate(world, n: int) -> float:
    """Team evaluations per second of the numpy rollout on the same team as :func:`kernel_rate`."""
    ic = world.initial_conditions(seed=0)
    genomes = np.random.default_rng(0).uniform(-2, 2, (world.n_rovers, world.n_params))
    t = time.perf_counter()
    for _ in range(n):
        numpy_rollout(world, genomes, ic).mean()
    return n / (time.perf_counter() - t)


def return_mismatches(world, teams: int) -> int:
    """Episodes whose return differs between kernel and numpy rollout, over random teams and starts."""
    rng = np.random.default_rng(1)
    bad = 0
    for t in range(teams):
        ic = world.initial_conditions(seed=100 + t)
        genomes = rng.uniform(-2, 2, (world.n_rovers, world.n_params))
        bad += int(np.sum(world.returns(genomes, ic) != numpy_rollout(world, genomes, ic)))
    return bad


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
    p.add_argument("--numpy-evals", type=int, default=150, help="numpy-rollout team evaluations per repeat")
    p.add_argument("--check-teams", type=int, default=20, help="random teams for the numpy returns check")
    a = p.parse_args()

    load_start = os.getloadavg()
    cfg = OmegaConf.to_container(compose_config(f"setup={a.setup}", f"k={a.k}"), resolve=True)
    world = make_world(a.setup)
    kernel_rate(world, 50)                                   # JIT / cache warm-up
    loop_rate(cfg, 50)
    numpy_rate(world, 5)
    mismatches = return_mismatches(world, a.check_teams)
    kernel, loop, numpy_ = [], [], []
    for _ in range(a.repeats):                               # alternate so machine noise hits all alike
        kernel.append(kernel_rate(world, a.evals))
        numpy_.append(numpy_rate(world, a.numpy_evals))
        loop.append(loop_rate(cfg, a.evals))
    k_med, l_med, n_med = statistics.median(kernel), statistics.median(loop), statistics.median(numpy_)
    agent_steps = world.episodes * world.steps * world.n_rovers
    print(json.dumps({
        "benchmark": "throughput", "setup": a.setup, "k": a.k, "repeats": a.repeats, "evals_per_repeat": a.evals,
        "team_evals_per_s": round(k_med, 1),
        "agent_steps_per_s": round(k_med * agent_steps, 1),
        "ns_per_agent_step": round(1e9 / (k_med * agent_steps), 1),
        "loop_team_evals_per_s": round(l_med, 1),
        "loop_over_kernel": round(statistics.median(lp / k for lp, k in zip(loop, kernel, strict=True)), 3),
        "numpy_team_evals_per_s": round(n_med, 1),
        "numpy_agent_steps_per_s": round(n_med * agent_steps, 1),
        "kernel_over_numpy": round(statistics.median(k / n for k, n in zip(kernel, numpy_, strict=True)), 2),
        "numpy_returns_equal": mismatches == 0,
        "numpy_return_mismatches": mismatches,
        "numpy_checked_episodes": a.check_teams * world.episodes,
        "agent_steps_per_team_eval": agent_steps,
        "kernel_runs": [round(x, 1) for x in kernel], "loop_runs": [round(x, 1) for x in loop],
        "numpy_runs": [round(x, 1) for x in numpy_],
        "loadavg_1m_start": round(load_start[0], 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(), "python": platform.python_version(),
    }))

if __name__ == "__main__":
    main()
