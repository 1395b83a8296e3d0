"""Single-core throughput of the default world: the fused rollout kernel (float64, and float32 as under
``env.dtype=float32``) against its frozen copy at commit 4c4ae3c (``benchmarks/kernel_4c4ae3c.py``), ``World.evaluate``,
the full generation loop (compiled, and CC11ES's Python loop: ``compiled_over_python_loop``), and the plain numpy
reference (``tests/reference.py``). Prints one JSON line.

    python benchmarks/throughput.py [--setup solo] [--repeats 7] [--evals 3000] [--numpy-evals 150]

The kernel and the old kernel get the same arguments (one team, the world's starts) and are checked bit for bit on
``--check-teams`` random teams and starts (returns, trajectories, final positions: ``kernel_equals_old``). Their speeds
are compared in ``--processes`` fresh processes, one after the other, loading the kernels in alternating order: where
the JIT places the code alone moves a kernel's speed by a few percent, so ``old_copy`` (the old kernel's code loaded a
second time) is timed as an A/A control (``old_copy_over_old``). In each repeat of each process the four run in
rotating order in ``--chunks`` chunks, so that machine noise hits them alike; ``kernel_over_old`` is the median of the
per-repeat ratios of rates (above 1: the new kernel is faster). The float32 kernel (``new32``: the same code on the same
team and starts cast to float32) runs in the same rotation: ``kernel32_over_old``. ``World.evaluate``, the generation
loop and the numpy reference are measured alternately in this process; the reference's per-episode returns are checked
against the kernel's (``numpy_return_mismatches`` counts differing episodes).

``stages_ns_per_agent_step`` times the rollout's stage loops alone (``sense_flat``, ``act_flat``, ``move_flat``)
on the world's starting states, and ``mlp_fma_per_agent_step`` counts the multiply-adds of the MLP there (the
non-zero input rows times H, plus the output layer), so ``act_fma_per_ns`` says how near the policy runs to the
core's multiply-add rate. That rate is measured too (``fma_per_ns_peak``: independent chains of float64
multiply-adds, vectorised, in L1), which gives this machine's float64 limit for the MLP's multiply-adds
(``mlp_float64_limit_ns_per_agent_step``) and how far the act stage is above it (``act_over_limit``).

Rates count process CPU time, which a shared, oversubscribed machine inflates less than wall time
(``kernel_over_old_wall`` is the kernel ratio in wall time).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import kernel_4c4ae3c as old_kernel  # same folder
import numpy as np
from numba import njit

from rovermarl import make_world
from rovermarl.config import compose_config
from rovermarl.env import kernel
from rovermarl.env.kernel.checks import input_rows
from rovermarl.env.kernel.math import FAST, sincos_all
from rovermarl.env.kernel.stages import act_flat, move_flat, sense_flat, to_flat
from rovermarl.runner.chunk import Run, to_plain

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))    # the repository root
from tests import reference  # noqa: E402 -- the SPEC in plain numpy, the tests' oracle


def kernel_inputs(world, seed: int = 0):
    """Arguments of ``rollout`` without its outputs: a random team, the world's starts and the world's arrays."""
    xy0, h0, _ = world.initial_conditions(seed=seed)
    genomes = np.random.default_rng(seed).uniform(-2, 2, (world.n_rovers, world.n_params))
    return (genomes, xy0, h0, world.poi_xy, world.task.sensor_type, world.task.coupling, world.task.value, world.steps,
            world.policy.hidden, float(world.sensor_range), float(world.obs_radius), float(world.v_max), world.w_max)


def as_float32(args):
    """The kernel's arguments as ``World.kernel_args`` gives them under ``env.dtype=float32`` (the genomes too)."""
    f = np.float32
    cast = [a.astype(f) if isinstance(a, np.ndarray) and a.dtype == np.float64 else a for a in args]
    cast[6] = args[6]                                                   # value: the reward reads float64
    return tuple(f(a) if isinstance(a, float) else a for a in cast)


def with_modes(rollout, args):
    """The arguments as ``rollout`` takes them: 4c4ae3c's kernel the world's arrays and numbers one by one; the
    current kernel the world as one :class:`~rovermarl.env.kernel.KernelWorld`, with ``speed_mode, reward_mode``
    (the SPEC reading: 0, 0)."""
    if rollout is not kernel.rollout:
        return args
    genomes, xy0, h0, poi_xy, poi_type, coupling, value, steps, hidden, *floats = args
    d = 3 * poi_xy.shape[0] + 2 * genomes.shape[0]
    return (genomes, xy0, h0, kernel.KernelWorld(poi_xy, poi_type, coupling, value, steps, hidden, d, *floats, 0, 0,
                                                 np.empty((h0.shape[0], 0)), (), input_rows(genomes.shape[0],
                                                 poi_type), np.empty(0, np.int64)))


def run_kernel(rollout, args, record: bool):
    """One rollout; returns (returns, traj_xy, traj_heading, final_xy) (empty arrays where not recorded)."""
    e, n = args[2].shape
    steps = args[7]
    if record:
        outs = (np.empty(e), np.empty((e, steps + 1, n, 2)), np.empty((e, steps + 1, n)), np.empty((e, n, 2)))
    else:
        outs = (np.empty(e), np.empty((0, 1, 1, 2)), np.empty((0, 1, 1)), np.empty((0, 1, 2)))
    rollout(*with_modes(rollout, args), *outs)
    return outs


def kernel_seconds(rollout, args, n: int) -> np.ndarray:
    """[CPU, wall] seconds for ``n`` fused rollouts (returns only, as in an evaluation)."""
    returns, no_xy, no_h, no_final = run_kernel(rollout, args, record=False)
    args = with_modes(rollout, args)
    c, w = time.process_time(), time.perf_counter()
    for _ in range(n):
        rollout(*args, returns, no_xy, no_h, no_final)
    return np.array([time.process_time() - c, time.perf_counter() - w])


def kernel_worker(a) -> None:
    """One fresh process: load the kernels in ``--load-order``, then time them in rotating order; print JSON."""
    kernels = {"new": kernel.rollout, "old": old_kernel.rollout,
               "old_copy": njit(**old_kernel._FAST)(old_kernel.rollout.py_func),  # A/A: same code, other address
               "new32": kernel.rollout}
    args64 = kernel_inputs(make_world(a.setup))
    inputs = {name: as_float32(args64) if name == "new32" else args64 for name in kernels}
    order = a.load_order.split(",")
    for name in order:
        run_kernel(kernels[name], inputs[name], record=False)           # JIT cache load, in this order
    per = max(1, a.evals // a.chunks)
    out = {name: [] for name in kernels}
    for r in range(a.repeats):
        total = {name: np.zeros(2) for name in kernels}
        for c in range(a.chunks):
            shift = (r + c) % len(order)
            for name in order[shift:] + order[:shift]:
                total[name] += kernel_seconds(kernels[name], inputs[name], per)
        for name in kernels:
            out[name].append((per * a.chunks / total[name]).tolist())        # [per CPU s, per wall s]
    print(json.dumps(out))


def kernel_vs_old(a) -> dict[str, np.ndarray]:
    """Rates (R, 2) [per CPU s, per wall s] of new, old and old_copy over ``--processes`` fresh processes (in turn,
    the load order alternating: code placement alone moves a kernel's speed by a few percent)."""
    rates = {"new": [], "old": [], "old_copy": [], "new32": []}
    for i in range(a.processes):
        order = "new,old,old_copy,new32" if i % 2 == 0 else "new32,old_copy,old,new"
        cmd = [sys.executable, __file__, "--kernel-worker", "--load-order", order, "--setup", a.setup,
               "--repeats", str(a.repeats), "--evals", str(a.evals), "--chunks", str(a.chunks)]
        out = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
        for name in rates:
            rates[name] += out[name]
    return {name: np.array(r) for name, r in rates.items()}


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


def loop_rate(cfg: dict, n: int, loop: str = "auto") -> float:
    """Generations (= team evaluations) per second of the full loop: choose, mutate, evaluate, select, record.
    ``loop``: "auto" (the compiled loop, which the default config takes) or "python" (CC11ES's Python loop)."""
    cfg = {**cfg, "generations": n, "algorithm": {**cfg["algorithm"], "loop": loop}}
    run = Run(cfg, seed=0)
    t = time.process_time()
    run.advance(n)
    return n / (time.process_time() - t)


@njit(**FAST)
def _stage_loop(which, reps, genomes, x, y, heading, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs, cand, n_ep,
                hidden, hid, rows, a0, a1, v_max, w_max):
    """``reps`` calls of one stage loop (0 sense, 1 act, 2 move) on fixed inputs; move works on copies."""
    for _ in range(reps):
        if which == 0:
            sense_flat(x, y, sin_h, cos_h, n, poi_xy, poi_type, sensor_range, obs)
        elif which == 1:
            act_flat(genomes, obs, cand, n_ep, hidden, hid, rows, a0, a1, True)
        else:
            move_flat(x.copy(), y.copy(), heading.copy(), sin_h.copy(), cos_h.copy(), a0, a1, v_max, w_max, 0)


def stage_profile(world, reps: int, repeats: int) -> dict:
    """ns per agent-step of each stage loop (best of ``repeats``), and the MLP's multiply-adds per agent-step."""
    genomes, xy0, h0 = kernel_inputs(world)[:3]
    n_ep, n = h0.shape
    ne, d = n * n_ep, 3 * world.poi_xy.shape[0] + 2 * n
    x, y, heading, sin_h, cos_h, a0, a1 = (np.empty(ne) for _ in range(7))
    to_flat(xy0[:, :, 0], x)
    to_flat(xy0[:, :, 1], y)
    to_flat(h0, heading)
    sincos_all(heading, sin_h, cos_h)
    obs = np.empty(d * ne)
    typ = world.task.sensor_type
    args = (genomes, x, y, heading, sin_h, cos_h, n, world.poi_xy, typ, float(world.sensor_range), obs,
            input_rows(n, typ), n_ep, world.policy.hidden, np.empty((world.policy.hidden + 2) * n_ep),
            np.empty(d, dtype=np.int64), a0, a1, float(world.v_max), world.w_max)
    out = {}
    for which, name in enumerate(("sense", "act", "move")):
        _stage_loop(which, 1, *args)
        best = min(_timed(lambda w=which: _stage_loop(w, reps, *args)) for _ in range(repeats))
        out[name] = round(best / (reps * ne) * 1e9, 2)
    rows = obs.reshape(d, n, n_ep).any(axis=2).sum(axis=0)                # non-zero input rows per rover
    fma = float(np.mean(rows)) * world.policy.hidden + 2 * world.policy.hidden
    peak = fma_peak(repeats)
    return {"stages_ns_per_agent_step": out, "mlp_fma_per_agent_step": round(fma, 1),
            "act_fma_per_ns": round(fma / out["act"], 2), "fma_per_ns_peak": round(peak, 2),
            "mlp_float64_limit_ns_per_agent_step": round(fma / peak, 2),
            "act_over_limit": round(out["act"] / (fma / peak), 2)}


@njit(**FAST)
def _fma_chains(a, b, c, reps):
    """``reps`` times 32 dependent multiply-adds on every element of ``a`` (M,): independent chains across the
    elements, vectorised over them, so the core's multiply-add throughput bounds the loop."""
    for _ in range(reps):
        for i in range(a.shape[0]):
            x = a[i]
            for _ in range(32):
                x = x * b + c
            a[i] = x


def fma_peak(repeats: int, reps: int = 2000) -> float:
    """float64 multiply-adds per ns of one core, measured (best of ``repeats``) on 2,048 values in L1."""
    a = np.random.default_rng(0).uniform(-1.0, 1.0, 2048)
    _fma_chains(a, 0.999999, 1e-7, 1)
    best = min(_timed(lambda: _fma_chains(a, 0.999999, 1e-7, reps)) for _ in range(repeats))
    return reps * a.shape[0] * 32 / best * 1e-9


def _timed(f) -> float:
    t = time.process_time()
    f()
    return time.process_time() - t


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="solo")
    p.add_argument("--k", default="1")
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--evals", type=int, default=3000, help="team evaluations per repeat and kernel")
    p.add_argument("--chunks", type=int, default=20, help="alternating chunks of kernel and old kernel per repeat")
    p.add_argument("--numpy-evals", type=int, default=150, help="numpy-reference team evaluations per repeat")
    p.add_argument("--check-teams", type=int, default=20, help="random teams for the equality checks")
    p.add_argument("--processes", type=int, default=4, help="fresh processes for the kernel comparison")
    p.add_argument("--kernel-worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--load-order", default="new,old,old_copy,new32", help=argparse.SUPPRESS)
    a = p.parse_args()

    if a.kernel_worker:
        kernel_worker(a)
        return
    load_start = os.getloadavg()
    cfg = to_plain(compose_config(f"setup={a.setup}", f"k={a.k}"))
    cfg32 = to_plain(compose_config(f"setup={a.setup}", f"k={a.k}", "env.dtype=float32"))
    world = make_world(a.setup)
    old_bad = old_mismatches(world, a.check_teams)
    numpy_bad = numpy_mismatches(world, a.check_teams)
    rates = kernel_vs_old(a)
    new, old = rates["new"][:, 0], rates["old"][:, 0]
    evaluate_rate(world, 50)                                 # warm-up
    loop_rate(cfg, 50)
    loop_rate(cfg, 50, "python")
    loop_rate(cfg32, 50)
    numpy_rate(world, 5)
    stages = stage_profile(world, reps=max(1, a.evals) * world.steps // 4, repeats=a.repeats)
    evaluate, loop, py_loop, loop32, numpy_ = [], [], [], [], []
    for _ in range(a.repeats):                               # alternate so machine noise hits all alike
        evaluate.append(evaluate_rate(world, a.evals))
        numpy_.append(numpy_rate(world, a.numpy_evals))
        loop.append(loop_rate(cfg, a.evals))
        py_loop.append(loop_rate(cfg, a.evals, "python"))
        loop32.append(loop_rate(cfg32, a.evals))
    med = statistics.median
    agent_steps = world.episodes * world.steps * world.n_rovers
    print(json.dumps({
        "benchmark": "throughput", "setup": a.setup, "k": a.k, "repeats": a.repeats, "evals_per_repeat": a.evals,
        "chunks": a.chunks, "clock": "process CPU time",
        "processes": a.processes,
        "kernel_evals_per_s": round(med(new), 1),
        "old_kernel_evals_per_s": round(med(old), 1),
        "kernel_over_old": round(med(new / old), 4),
        "kernel_over_old_per_process": [round(med(x), 4) for x in np.split(new / old, a.processes)],
        "kernel_over_old_runs": [round(x, 4) for x in new / old],
        "kernel_over_old_wall": round(med(rates["new"][:, 1] / rates["old"][:, 1]), 4),
        "kernel32_evals_per_s": round(med(rates["new32"][:, 0]), 1),
        "kernel32_over_old": round(med(rates["new32"][:, 0] / old), 4),
        "kernel32_over_old_per_process": [round(med(x), 4) for x in np.split(rates["new32"][:, 0] / old,
                                                                             a.processes)],
        "kernel32_over_kernel": round(med(rates["new32"][:, 0] / new), 4),
        "ns_per_agent_step_float32": round(1e9 / (med(rates["new32"][:, 0]) * agent_steps), 2),
        "old_copy_over_old": round(med(rates["old_copy"][:, 0] / old), 4),
        "old_copy_over_old_per_process": [round(med(x), 4) for x in np.split(rates["old_copy"][:, 0] / old,
                                                                             a.processes)],
        "ns_per_agent_step": round(1e9 / (med(new) * agent_steps), 2),
        "old_ns_per_agent_step": round(1e9 / (med(old) * agent_steps), 2),
        "kernel_equals_old": old_bad == 0,
        "kernel_old_mismatched_teams": old_bad,
        "team_evals_per_s": round(med(evaluate), 1),
        "agent_steps_per_s": round(med(evaluate) * agent_steps, 1),
        "evaluate_over_kernel": round(med(evaluate) / med(new), 3),
        "loop_team_evals_per_s": round(med(loop), 1),
        "loop_over_kernel": round(med(loop) / med(new), 3),
        "python_loop_team_evals_per_s": round(med(py_loop), 1),
        "compiled_over_python_loop": round(med(np.array(loop) / np.array(py_loop)), 3),
        "loop_float32_team_evals_per_s": round(med(loop32), 1),
        "loop_float32_over_loop": round(med(np.array(loop32) / np.array(loop)), 3),
        **stages,
        "numpy_team_evals_per_s": round(med(numpy_), 1),
        "kernel_over_numpy": round(med(new) / med(numpy_), 2),
        "numpy_returns_equal": numpy_bad == 0,
        "numpy_return_mismatches": numpy_bad,
        "checked_teams": a.check_teams, "checked_episodes": a.check_teams * world.episodes,
        "agent_steps_per_team_eval": agent_steps,
        "evaluate_runs": [round(x, 1) for x in evaluate], "loop_runs": [round(x, 1) for x in loop],
        "python_loop_runs": [round(x, 1) for x in py_loop],
        "numpy_runs": [round(x, 1) for x in numpy_],
        "loadavg_1m_start": round(load_start[0], 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(), "python": platform.python_version(),
    }))


if __name__ == "__main__":
    main()
