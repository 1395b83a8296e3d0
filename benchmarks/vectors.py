"""512-bit against 256-bit vectors (``rovermarl/env/kernel/target.py``): ``World.evaluate`` of one team in fresh
processes built for a CPU that LLVM tunes to prefer 256-bit vectors (``--cpu``, default Skylake-SP), with
``ROVERMARL_VECTORS=512`` and ``off``, and for the host as rovermarl builds by default. Prints one JSON line.

    python benchmarks/vectors.py [--rounds 3] [--evals 2000] [--cpu skylake-avx512]

The three run in alternating order ``--rounds`` times; each process reports its best of 5 timings (process CPU
time) after a warm-up call that compiles or loads the kernel. ``wide_over_narrow`` is the median of the per-round
ratios. Needs a CPU with AVX-512 to run the code built for ``--cpu``; the speeds of a real Intel CPU may differ.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def worker(evals: int) -> None:
    import numpy as np

    from rovermarl import make_world
    from rovermarl.env.kernel import target

    world = make_world("solo")
    genomes = np.random.default_rng(0).uniform(-2, 2, (world.n_rovers, world.n_params))
    ic = world.initial_conditions(seed=0)
    world.evaluate(genomes, ic)
    best = 0.0
    for _ in range(5):
        t = time.process_time()
        for _ in range(evals):
            world.evaluate(genomes, ic)
        best = max(best, evals / (time.process_time() - t))
    print(json.dumps({"evals_per_s": best, "features_set": target.SET is not None}))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--evals", type=int, default=2000)
    p.add_argument("--cpu", default="skylake-avx512")
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.worker:
        worker(a.evals)
        return
    base = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_NAME", "NUMBA_CPU_FEATURES",
                                                              "ROVERMARL_VECTORS")}
    sides = {"wide": {"ROVERMARL_VECTORS": "512", "NUMBA_CPU_NAME": a.cpu},
             "narrow": {"ROVERMARL_VECTORS": "off", "NUMBA_CPU_NAME": a.cpu}, "host_default": {}}
    rates = {name: [] for name in sides}
    for _ in range(a.rounds):
        for name, extra in sides.items():
            out = subprocess.run([sys.executable, __file__, "--worker", "--evals", str(a.evals)], env={**base, **extra},
                                 capture_output=True, text=True, check=True).stdout
            rates[name].append(json.loads(out.strip().splitlines()[-1])["evals_per_s"])
    ratio = [w / n for w, n in zip(rates["wide"], rates["narrow"], strict=True)]
    print(json.dumps({
        "benchmark": "vectors", "cpu": a.cpu, "rounds": a.rounds, "evals": a.evals, "clock": "process CPU time",
        "evals_per_s": {name: [round(x, 1) for x in v] for name, v in rates.items()},
        "wide_over_narrow": round(statistics.median(ratio), 3),
        "host_default_over_wide": round(statistics.median(h / w for h, w in zip(rates["host_default"],
                                                                                 rates["wide"], strict=True)), 3),
        "loadavg_1m": round(os.getloadavg()[0], 2), "cpus": os.cpu_count(),
    }))


if __name__ == "__main__":
    main()
