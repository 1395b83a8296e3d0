"""Single-core throughput of the default world: the fused rollout kernel against its frozen copy at commit 4c4ae3c
(``benchmarks/kernel_4c4ae3c.py``), ``World.evaluate``, the full generation loop, and the plain numpy reference
(``rovermarl.env.reference``). Prints one JSON line.

    python benchmarks/throughput.py [--setup solo] [--repeats 7] [--evals 3000] [--numpy-evals 150]

The kernel and the old kernel get the same arguments (one team, the world's starts). In each repeat they run
alternately in ``--chunks`` chunks, so that machine noise hits both alike; ``kernel_over_old`` is the median of the
per-repeat ratios of their rates (above 1: the kernel is faster). Their returns, trajectories and final positions
are compared bit for bit on ``--check-teams`` random teams and starts (``kernel_equals_old``). ``World.evaluate``,
the loop and the numpy reference are measured alternately too; the reference's per-episode returns are checked
against the kernel's (``numpy_return_mismatches`` counts differing episodes).

Rates count the process CPU time, which a shared, oversubscribed machine inflates less than wall time
(``kernel_over_old_wall`` is the kernel ratio in wall time).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import kernel_4c4ae3c as old_kernel  # same folder
import numpy as np

from rovermarl import make_world
from rovermarl.config import compose_config
from rovermarl.env import kernel, reference
from rovermarl.runner.chunk import Run, to_plain


def kernel_inputs(world, seed: int = 0):
    """Arguments of ``rollout`` without its outputs: a random team, the world's starts and the world's arrays."""
    xy0, h0 = world.initial_conditions(seed=seed)
    genomes = np.random.default_rng(seed).uniform(-2, 2, (world.n_rovers, world.n_params))
    return (genomes, xy0, h0, world.poi_xy, world._type, world._coupling, world._value, world.steps, world.hidden,
            float(world.sensor_range), float(world.obs_radius), float(world.v_max), world.w_max)


def run_kernel(rollout, args, record: bool):
    """One rollout; returns (returns, traj_xy, traj_heading, final_xy) (empty arrays where not recorded)."""
    e, n = args[2].shape
    steps = args[7]
    if record:
        outs = (np.empty(e), np.empty((e, steps + 1, n, 2)), np.empty((e, steps + 1, n)), np.empty((e, n, 2)))
    else:
        outs = (np.empty(e), np.empty((0, 1, 1, 2)), np.empty((0, 1, 1)), np.empty((0, 1, 2)))
    rollout(*args, *outs)
    return outs


def kernel_seconds(rollout, args, n: int) -> np.ndarray:
    """[CPU, wall] seconds for ``n`` fused rollouts (returns only, as in an evaluation)."""
    returns, no_xy, no_h, no_final = run_kernel(rollout, args, record=False)
    c, w = time.process_time(), time.perf_counter()
    for _ in range(n):
        rollout(*args, returns, no_xy, no_h, no_final)
    return np.array([time.process_time() - c, time.perf_counter() - w])


def kernel_vs_old(args, n: int, chunks: int, first_new: bool) -> tuple[np.ndarray, np.ndarray]:
    """Rates [per CPU second, per wall second] of the kernel and of the old kernel, alternating in ``chunks``."""
    new_s, old_s = np.zeros(2), np.zeros(2)
    per = max(1, n // chunks)
    for c in range(chunks):
        if (c % 2 == 0) == first_new:
            new_s += kernel_seconds(kernel.rollout, args, per)
            old_s += kernel_seconds(old_kernel.rollout, args, per)
        else:
            old_s += kernel_seconds(old_kernel.rollout, args, per)
            new_s += kernel_seconds(kernel.rollout, args, per)
    return per * chunks / new_s, per * chunks / old_s


def old_mismatches(world, teams: int) -> int:
    """Random teams and starts on which the kernel and the old kernel differ in any bit of any output."""
    bad = 0
    for t in range(teams):
        args = kernel_inputs(world, seed=100 + t)
        new = run_kernel(kernel.rollout, args, record=True)
        old = run_kernel(old_kernel.rollout, args, record=True)
        bad += any(a.tobytes() != b.tobytes() for a, b in zip(new, old, strict=True))
    return bad


def evaluate_rate(world, n: int) -> float:
    """Team evaluations per second of ``world.evaluate`` (the kernel and its Python wrapper) on a fixed team."""
    genomes, xy0, h0 = kernel_inputs(world)[:3]
    t = time.process_time()
    for _ in range(n):
        world.evaluate(genomes, (xy0, h0))
    return n / (time.process_time() - t)


def numpy_rate(world, n: int) -> float:
    """Team evaluations per second of the numpy reference on the same team as :func:`evaluate_rate`."""
    genomes, xy0, h0 = kernel_inputs(world)[:3]
    t = time.process_time()
    for _ in range(n):
        reference.rollout(world, genomes, (xy0, h0)).mean()
    return n / (time.process_time() - t)


def numpy_mismatches(world, teams: int) -> int:
    """Episodes whose return differs between the kernel and the numpy reference, over random teams and starts."""
    rng = np.random.default_rng(1)
    bad = 0
    for t in range(teams):
        ic = world.initial_conditions(seed=100 + t)
        genomes = rng.uniform(-2, 2, (world.n_rovers, world.n_params))
        bad += int(np.sum(world.returns(genomes, ic) != reference.rollout(world, genomes, ic)))
    return bad


def loop_rate(cfg: dict, n: int) -> float:
    """Generations (= team evaluations) per second of the full loop: choose, mutate, evaluate, select, record."""
    run = Run({**cfg, "generations": n}, seed=0)
    t = time.process_time()
    run.advance(n)
    return n / (time.process_time() - t)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="solo")
    p.add_argument("--k", default="1")
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--evals", type=int, default=3000, help="team evaluations per repeat and kernel")
    p.add_argument("--chunks", type=int, default=20, help="alternating chunks of kernel and old kernel per repeat")
    p.add_argument("--numpy-evals", type=int, default=150, help="numpy-reference team evaluations per repeat")
    p.add_argument("--check-teams", type=int, default=20, help="random teams for the equality checks")
    a = p.parse_args()

    load_start = os.getloadavg()
    cfg = to_plain(compose_config(f"setup={a.setup}", f"k={a.k}"))
    world = make_world(a.setup)
    args = kernel_inputs(world)
    kernel_vs_old(args, 50, 2, True)                         # JIT / cache warm-up
    evaluate_rate(world, 50)
    loop_rate(cfg, 50)
    numpy_rate(world, 5)
    old_bad = old_mismatches(world, a.check_teams)
    numpy_bad = numpy_mismatches(world, a.check_teams)
    new, old, ratio, wall_ratio, evaluate, loop, numpy_ = [], [], [], [], [], [], []
    for r in range(a.repeats):                               # alternate so machine noise hits all alike
        k_new, k_old = kernel_vs_old(args, a.evals, a.chunks, first_new=r % 2 == 0)
        new.append(k_new[0])
        old.append(k_old[0])
        ratio.append(k_new[0] / k_old[0])
        wall_ratio.append(k_new[1] / k_old[1])
        evaluate.append(evaluate_rate(world, a.evals))
        numpy_.append(numpy_rate(world, a.numpy_evals))
        loop.append(loop_rate(cfg, a.evals))
    med = statistics.median
    agent_steps = world.episodes * world.steps * world.n_rovers
    print(json.dumps({
        "benchmark": "throughput", "setup": a.setup, "k": a.k, "repeats": a.repeats, "evals_per_repeat": a.evals,
        "chunks": a.chunks, "clock": "process CPU time",
        "kernel_evals_per_s": round(med(new), 1),
        "old_kernel_evals_per_s": round(med(old), 1),
        "kernel_over_old": round(med(ratio), 4),
        "kernel_over_old_runs": [round(x, 4) for x in ratio],
        "kernel_over_old_wall": round(med(wall_ratio), 4),
        "ns_per_agent_step": round(1e9 / (med(new) * agent_steps), 2),
        "old_ns_per_agent_step": round(1e9 / (med(old) * agent_steps), 2),
        "kernel_equals_old": old_bad == 0,
        "kernel_old_mismatched_teams": old_bad,
        "team_evals_per_s": round(med(evaluate), 1),
        "agent_steps_per_s": round(med(evaluate) * agent_steps, 1),
        "evaluate_over_kernel": round(med(e / k for e, k in zip(evaluate, new, strict=True)), 3),
        "loop_team_evals_per_s": round(med(loop), 1),
        "loop_over_kernel": round(med(lp / k for lp, k in zip(loop, new, strict=True)), 3),
        "numpy_team_evals_per_s": round(med(numpy_), 1),
        "kernel_over_numpy": round(med(k / n for k, n in zip(new, numpy_, strict=True)), 2),
        "numpy_returns_equal": numpy_bad == 0,
        "numpy_return_mismatches": numpy_bad,
        "checked_teams": a.check_teams, "checked_episodes": a.check_teams * world.episodes,
        "agent_steps_per_team_eval": agent_steps,
        "kernel_runs": [round(x, 1) for x in new], "old_kernel_runs": [round(x, 1) for x in old],
        "evaluate_runs": [round(x, 1) for x in evaluate], "loop_runs": [round(x, 1) for x in loop],
        "numpy_runs": [round(x, 1) for x in numpy_],
        "loadavg_1m_start": round(load_start[0], 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(), "python": platform.python_version(),
    }))


if __name__ == "__main__":
    main()
