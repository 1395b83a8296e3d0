"""How the MLP's hidden layer sums its inputs, measured: the kernel's ``_mlp`` (register tiles of 8 hidden units x 8
float64 or 16 float32 episodes, ``rovermarl/env/kernel/simd.py``) against plain loops that numba's vectoriser handles,
with R input rows by W hidden units per pass over the episodes (``4x2`` was the kernel's until the tiles came). Every
variant adds each (unit, episode)'s inputs in the same order, so all are bit-identical (checked: ``equal``). Prints one
JSON line.

    python benchmarks/mlp_blocking.py [--setup solo] [--reps 20000] [--repeats 15] [--variants 4x2,4x4,8x1]
                                      [--dtype float64|float32]

Each variant is compiled with the kernel's options (FMA contraction only) and timed in the same process as the
kernel's ``_mlp``, in rotating order, on one team's observations of random rover states. ``ns_per_agent_step`` is
the best of ``--repeats``; ``over_kernel`` the median of the per-repeat speed ratios (above 1: faster than the
kernel). ``kernel_again`` is the kernel's own code compiled again: an A/A control for code placement and noise.
``no_tanh`` is the kernel with its hidden tanh replaced by a multiply, ``no_matmul_no_tanh`` also without the
hidden layer's multiply-adds (wrong results, ``equal`` false): ``act_parts_ns`` splits the act stage into the hidden
layer's multiply-adds, its tanh and the rest (biases, the zero-row scan, the output layer, also in register tiles,
and its tanh).
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import time

import numpy as np
from numba import njit

from rovermarl import make_world
from rovermarl.env.kernel import math as kmath
from rovermarl.env.kernel import simd
from rovermarl.env.kernel.checks import input_rows
from rovermarl.env.kernel.math import FAST, sincos_all
from rovermarl.env.kernel.stages import _lane0, _mlp, _squash, sense_flat

SPLIT = "    # -- the hidden layer's sums"             # the kernel's hidden-layer sums start here ...
RESUME = "    # -- the hidden layer's tanh"             # ... and end here
SQUASH = """    if finite:
        _squash(hid, p0, True)
    else:
        _squash(hid, p0, False)
"""                                                    # the kernel's hidden tanh
BIASES = """    for u in range(hidden):
        b = genomes[U(i), U(o_b1 + u)]
        for e in range(ep):
            hid[U(u * ep + e)] = b
"""                                                    # the sums' start, where the kernel's tiles do not give it


def kernel_parts() -> tuple[str, str, str]:
    """The kernel's ``_mlp`` source (from ``def``) in three: before its hidden-layer sums, the sums, the rest."""
    source = inspect.getsource(_mlp.py_func)
    if SPLIT not in source or RESUME not in source or SQUASH not in source:
        raise RuntimeError("the kernel's _mlp changed shape: update benchmarks/mlp_blocking.py")
    source = source[source.index("def _mlp("):]
    a, b = source.index(SPLIT), source.index(RESUME)
    return source[:a], source[a:b], source[b:]


def kernel_source(sums: bool = True, squash: str | None = None) -> str:
    """The kernel's ``_mlp``; without its hidden-layer sums (the biases only) unless ``sums``; with ``hid[v] =
    squash`` for the hidden tanh if given."""
    head, middle, tail = kernel_parts()
    if squash is not None:
        tail = tail.replace(SQUASH, f"    for v in range(hidden * ep):\n        hid[v] = {squash}\n")
    return head + (middle if sums else BIASES) + tail


def chain(acc: str, rows: int, weight) -> str:
    """``(((acc + obs[o0 + x] * w0) + obs[o1 + x] * w1) ...)``: the inputs in index order."""
    for i in range(rows):
        acc = f"({acc} + obs[o{i} + x] * {weight(i)})"
    return acc


def variant_source(rows: int, units: int) -> str:
    """Source of ``_mlp`` whose hidden-layer sums take ``rows`` input rows by ``units`` hidden units per pass over
    the episodes (loops that numba's vectoriser handles), then the remaining rows one by one; the rest (biases,
    zero-row scan, tanh, output layer) is the kernel's own code."""
    head, _, tail = kernel_parts()
    lines = [head.rstrip("\n"), BIASES.rstrip("\n"), f"    n4 = nr - nr % {rows}",
             f"    hb = hidden - hidden % {units}", f"    for r in range(0, n4, {rows}):"]
    for i in range(rows):
        lines += [f"        o{i} = U(rows[r + {i}] * ne + q0)", f"        kw{i} = U(rows[r + {i}] * hidden)"]
    lines.append(f"        for u in range(0, hb, {units}):")
    for j in range(units):
        lines += [f"            w{i}_{j} = genomes[U(i), kw{i} + U(u + {j})]" for i in range(rows)]
        lines.append(f"            h{j} = U((u + {j}) * ep)")
    lines += ["            for e in range(ep):", "                x = U(e)"]
    lines += [f"                hid[h{j} + x] = {chain(f'hid[h{j} + x]', rows, lambda i, j=j: f'w{i}_{j}')}"
              for j in range(units)]
    lines += ["        for u in range(hb, hidden):"]
    lines += [f"            v{i} = genomes[U(i), kw{i} + U(u)]" for i in range(rows)]
    lines += ["            h = U(u * ep)", "            for e in range(ep):", "                x = U(e)",
              f"                hid[h + x] = {chain('hid[h + x]', rows, lambda i: f'v{i}')}"]
    lines += ["    for r in range(n4, nr):", "        ok = U(rows[r] * ne + q0)", "        for u in range(hidden):",
              "            w = genomes[U(i), U(rows[r] * hidden + u)]", "            for e in range(ep):",
              "                hid[U(u * ep + e)] += obs[ok + U(e)] * w"]
    return "\n".join(lines) + "\n" + tail


def compile_variant(source: str):
    """``source`` compiled with the kernel's options (not cached: it has no file)."""
    namespace = {"U": np.uint64, "tanh": kmath.tanh, "like": kmath.like, "hidden_tile": simd.hidden_tile,
                 "output_tile": simd.output_tile, "output_tile2": simd.output_tile2, "UNITS": simd.UNITS,
                 "lanes": simd.lanes, "_squash": _squash, "_lane0": _lane0}
    exec(source, namespace)                                                  # noqa: S102 - our own template
    options = {k: v for k, v in FAST.items() if k != "cache"}
    return njit(**options)(namespace["_mlp"])


def team_loop(mlp):
    """A compiled loop of ``reps`` calls of ``mlp`` for every rover of a team, then the output tanh of all of them
    (as ``act_flat`` does): the act stage of one step."""
    @njit(**{k: v for k, v in FAST.items() if k != "cache"})
    def loop(genomes, obs, cand, n_ep, hidden, reps, hid, rows, a0, a1):
        ne = a0.shape[0]
        for _ in range(reps):
            for i in range(genomes.shape[0]):
                mlp(genomes, i, obs, cand, n_ep, hidden, hid, rows, True)
                for e in range(n_ep):
                    a0[i * n_ep + e] = hid[hidden * n_ep + e]
                    a1[i * n_ep + e] = hid[(hidden + 1) * n_ep + e]
            for q in range(ne):
                a0[q] = kmath.tanh(a0[q], True)
            for q in range(ne):
                a1[q] = kmath.tanh(a1[q], True)
    return loop


def inputs(world, seed: int = 0, dtype=np.float64):
    """A random team and its observations of random rover states inside the POI field (dense inputs), in
    ``dtype``."""
    rng = np.random.default_rng(seed)
    n_ep, n = world.episodes, world.n_rovers
    ne, d = n * n_ep, 3 * world.poi_xy.shape[0] + 2 * n
    lo, hi = world.poi_xy.min(axis=0), world.poi_xy.max(axis=0)
    x, y = rng.uniform(lo[0], hi[0], ne), rng.uniform(lo[1], hi[1], ne)
    heading, sin_h, cos_h = rng.uniform(-np.pi, np.pi, ne), np.empty(ne), np.empty(ne)
    sincos_all(heading, sin_h, cos_h)
    obs = np.empty(d * ne)
    sense_flat(x, y, sin_h, cos_h, n, world.poi_xy, world.task.sensor_type, float(world.sensor_range), obs)
    genomes = rng.uniform(-2, 2, (n, world.n_params))
    rows = input_rows(n, world.task.sensor_type)
    return genomes.astype(dtype), obs.astype(dtype), rows, n_ep, world.policy.hidden, d, ne


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="solo")
    p.add_argument("--reps", type=int, default=20000, help="team act stages per timing")
    p.add_argument("--repeats", type=int, default=15)
    p.add_argument("--dtype", default="float64", choices=("float64", "float32"), help="the kernel's precision")
    p.add_argument("--variants", default="4x2,4x1,2x2,8x1,8x2,4x4,2x4,1x16",
                   help="ROWSxUNITS per pass, comma-separated")
    a = p.parse_args()
    f = np.dtype(a.dtype).type
    genomes, obs, cand, n_ep, hidden, d, ne = inputs(make_world(a.setup), dtype=f)
    options = {k: v for k, v in FAST.items() if k != "cache"}
    mlps = {"kernel": _mlp, "kernel_again": njit(**options)(_mlp.py_func),
            "no_tanh": compile_variant(kernel_source(squash="hid[v] * like(hid[v], 0.5)")),
            "no_matmul_no_tanh": compile_variant(kernel_source(sums=False, squash="hid[v] * like(hid[v], 0.5)"))}
    for v in a.variants.split(","):
        rows, units = (int(s) for s in v.split("x"))
        mlps[v] = compile_variant(variant_source(rows, units))
    loops, outs = {}, {}
    for name, mlp in mlps.items():
        loops[name] = team_loop(mlp)
        outs[name] = (np.empty(ne, f), np.empty(ne, f))
        loops[name](genomes, obs, cand, n_ep, hidden, 1, np.empty((hidden + 2) * n_ep, f), np.empty(d, np.int64),
                    *outs[name])
    names = list(loops)
    seconds = {name: [] for name in names}
    for r in range(a.repeats):                                       # rotating order: noise hits all alike
        for name in names[r % len(names):] + names[:r % len(names)]:
            t = time.process_time()
            loops[name](genomes, obs, cand, n_ep, hidden, a.reps, np.empty((hidden + 2) * n_ep, f),
                        np.empty(d, np.int64), np.empty(ne, f), np.empty(ne, f))
            seconds[name].append(time.process_time() - t)
    ns = {name: min(seconds[name]) / (a.reps * ne) * 1e9 for name in names}
    kernel_s = np.array(seconds["kernel"])
    ref = outs["kernel"]
    print(json.dumps({
        "benchmark": "mlp_blocking", "setup": a.setup, "dtype": a.dtype, "reps": a.reps, "repeats": a.repeats,
        "clock": "process CPU time", "cpus": os.cpu_count(),
        "ns_per_agent_step": {name: round(v, 2) for name, v in ns.items()},
        "over_kernel": {name: round(float(np.median(kernel_s / np.array(seconds[name]))), 3) for name in names},
        "equal": {name: all(np.array_equal(x, y) for x, y in zip(outs[name], ref, strict=True)) for name in names},
        "tanh_share_of_act": round(1 - ns["no_tanh"] / ns["kernel"], 3),
        "act_parts_ns": {"hidden_layer_multiply_adds": round(ns["no_tanh"] - ns["no_matmul_no_tanh"], 2),
                         "hidden_tanh": round(ns["kernel"] - ns["no_tanh"], 2),
                         "rest": round(ns["no_matmul_no_tanh"], 2)},
    }))


if __name__ == "__main__":
    main()
