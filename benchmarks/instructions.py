"""Instructions per ``World.evaluate`` call, this package against another source tree, counted by valgrind's
callgrind: a count that another process on the machine does not change, where timings on this shared 2-core machine
spread by 2-10% between probes (docs/PERFORMANCE.md). Each tree runs in its own process under callgrind: it builds
the duo world, scores a zero-scoring team 20 times, then callgrind's counters are zeroed (``callgrind_control -z``),
``--calls`` calls run, and the counters are dumped (``callgrind_control -d``). Prints one JSON line: each tree's
instructions per call (the Python wrapper and the compiled rollout) and this package / the other tree; with
``--bus``, also the atomic (``lock``-prefixed) instructions per call (callgrind's ``Ge`` event: numba's reference
counts are atomic adds, which cost many cycles each and one instruction); with ``--cache``, the first-level and
last-level cache misses per call (callgrind's cache simulation); with ``--loop``, per generation of the compiled
CC-(1+1)-ES loop instead (duo, EXP3). Instrumentation starts at the zeroing (imports and warm-up run
uninstrumented).

    git worktree add /tmp/old 2f7d6b8 && python benchmarks/instructions.py /tmp/old --dtype float64

Under callgrind a process runs about 50x slower: its imports take about 10 minutes on this machine.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CHILD = """
import os, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
from rovermarl import make_world
n, dtype, sync = int(sys.argv[2]), sys.argv[3], sys.argv[4]
world = make_world("duo", dtype=dtype)
p = world.prepare(world.run_ic(0))
teams = np.random.default_rng(0).uniform(-2, 2, (256, world.n_rovers, world.n_params))
zero = teams[np.flatnonzero(world.evaluate_many(teams, p, workers=1) == 0)[0]]
for _ in range(20):
    world.evaluate(zero, p)
def handshake(name):
    open(os.path.join(sync, name), "w").close()
    while not os.path.exists(os.path.join(sync, name + ".ok")):
        time.sleep(0.2)
handshake("zero")
for _ in range(n):
    world.evaluate(zero, p)
handshake("dump")
"""
LOOP_CHILD = """
import os, sys, time
sys.path.insert(0, sys.argv[1])
from rovermarl.config import compose_config
from rovermarl.runner.chunk import Run, to_plain
n, dtype, sync = int(sys.argv[2]), sys.argv[3], sys.argv[4]
run = Run(to_plain(compose_config("setup=duo", "k=adaptive", "generations=100000000", "algorithm.loop=compiled",
                                  f"env.dtype={dtype}")), 0)
run.advance(200)
def handshake(name):
    open(os.path.join(sync, name), "w").close()
    while not os.path.exists(os.path.join(sync, name + ".ok")):
        time.sleep(0.2)
handshake("zero")
run.advance(n)
handshake("dump")
"""


def count(tree: Path, calls: int, dtype: str, bus: bool = False, cache: bool = False,
          child: str = CHILD) -> dict[str, float]:
    """Callgrind's events per call of ``World.evaluate`` in ``tree`` (holding rovermarl/): ``Ir`` (instructions),
    with ``bus`` ``Ge`` (atomic instructions), with ``cache`` ``D1mr``, ``D1mw``, ``DLmr``, ``DLmw``, ``I1mr``, ...
    (first- and last-level misses)."""
    with tempfile.TemporaryDirectory(prefix="rovermarl-ir-") as sync:
        out = Path(sync) / "cg.out"
        extra = ["--collect-bus=yes"] * bus + ["--cache-sim=yes"] * cache
        proc = subprocess.Popen(["valgrind", "--tool=callgrind", "--instr-atstart=no", *extra,
                                 f"--callgrind-out-file={out}", sys.executable,
                                 "-c", child, str(tree), str(calls), dtype, sync],
                                env={**os.environ, "PYTHONHASHSEED": "0"}, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        for step, commands in (("zero", (("-i", "on"), ("-z",))), ("dump", (("-d",),))):
            while not (Path(sync) / step).exists():
                if proc.poll() is not None:
                    sys.exit(f"benchmarks/instructions.py: the child in {tree} ended (exit {proc.returncode})")
                time.sleep(1)
            for flags in commands:              # instrumentation on, counters zeroed; then the dump
                subprocess.run(["callgrind_control", *flags, str(proc.pid)], check=True, capture_output=True)
            (Path(sync) / f"{step}.ok").touch()
        proc.wait()
        dumps = [p for p in Path(sync).glob("cg.out*") if p != out]   # the dump made at "dump": cg.out.1
        text = dumps[0].read_text()
        events = re.search(r"^events: (.+)$", text, flags=re.M)[1].split()
        totals = re.search(r"^summary: (.+)$", text, flags=re.M)[1].split()
        return {e: int(v) / calls for e, v in zip(events, totals, strict=False)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("other", type=Path, help="the other tree's root (holding rovermarl/ and conf/)")
    p.add_argument("--calls", type=int, default=400)
    p.add_argument("--dtype", choices=("float64", "float32"), default="float64")
    p.add_argument("--bus", action="store_true", help="count atomic instructions too (callgrind --collect-bus)")
    p.add_argument("--cache", action="store_true", help="count cache misses too (callgrind --cache-sim)")
    p.add_argument("--loop", action="store_true", help="count per generation of the compiled CC-(1+1)-ES loop (duo, "
                   "k=adaptive, after 200 generations) instead of per World.evaluate call")
    a = p.parse_args()
    if not (shutil.which("valgrind") and shutil.which("callgrind_control")):
        sys.exit("benchmarks/instructions.py: needs valgrind (callgrind, callgrind_control) on PATH")
    child = LOOP_CHILD if a.loop else CHILD
    mine, other = (count(t, a.calls, a.dtype, a.bus, a.cache, child) for t in (ROOT, a.other.resolve()))
    print(json.dumps({"benchmark": "instructions", "per": "generation" if a.loop else "call", "dtype": a.dtype,
                      "calls": a.calls, "package": str(ROOT),
                      "other": str(a.other.resolve()), "package_per_call": round(mine["Ir"]),
                      "other_per_call": round(other["Ir"]), "package_over_other": round(mine["Ir"] / other["Ir"], 4),
                      "package_events": {e: round(v, 1) for e, v in mine.items()},
                      "other_events": {e: round(v, 1) for e, v in other.items()}}))


if __name__ == "__main__":
    main()
