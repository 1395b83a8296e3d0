"""Memory and checkpoint bytes against the budget: one serial run of G generations in a fresh process, for each G.

Prints one JSON line: per G the peak RSS of that process (``ru_maxrss``), the largest checkpoint written, and the
wall time; and ``rss_growth_mb`` between the smallest and the largest G (the promise: within 250 MB from 20,000 to
500,000 generations).

    python benchmarks/memory.py [--generations 20000 500000] [--setup duo] [--k 1]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = """
import resource, sys, threading, time
from pathlib import Path
from rovermarl.config import compose_config
from rovermarl.runner.job import run_job
out = Path(sys.argv[1])
largest = [0]
def watch():
    while not done:
        for p in out.glob("runs/*/checkpoint*.bin"):
            try:
                largest[0] = max(largest[0], p.stat().st_size)
            except OSError:
                pass
        time.sleep(0.2)
done = False
t = threading.Thread(target=watch, daemon=True)
t.start()
run_job(compose_config(*sys.argv[2:]), out)
done = True
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, largest[0])
"""


def measure(generations: int, setup: str, k: str) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", CHILD, str(Path(tmp) / "job"), f"generations={generations}",
                               "seeds=1", f"setup={setup}", f"k={k}", "parallel=serial", "checkpoint.every=4000"],
                              capture_output=True, text=True, check=True)
        rss_kb, ckpt = (int(x) for x in proc.stdout.split()[-2:])
        return {"generations": generations, "peak_rss_mb": rss_kb / 1024, "largest_checkpoint_bytes": ckpt,
                "wall_s": time.perf_counter() - t0}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--generations", type=int, nargs="+", default=[20_000, 500_000])
    p.add_argument("--setup", default="duo")
    p.add_argument("--k", default="1")
    args = p.parse_args()
    runs = [measure(g, args.setup, args.k) for g in sorted(args.generations)]
    print(json.dumps({"benchmark": "memory", "setup": args.setup, "k": args.k, "runs": runs,
                      "rss_growth_mb": runs[-1]["peak_rss_mb"] - runs[0]["peak_rss_mb"],
                      "self_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


if __name__ == "__main__":
    main()
