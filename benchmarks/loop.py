"""CC-(1+1)-ES's one generation loop (``rovermarl.algorithms.generation.generations``) both ways, for the same runs:
run as Python over the Python operations (``algorithm.loop=python``, ``cc11es.PYTHON``) against compiled over the
compiled ones (``compiled``, ``compiled.COMPILED``), bit-identical (checked). Prints one JSON line: CPU-seconds per
chunk of each (medians over repeats, alternated in one process) and ``python_over_compiled`` = the compiled way's
speed-up.

    python benchmarks/loop.py            # about 10 s once compiled

``--other TREE`` times the compiled way only (500-generation chunks after 200, median of 9), this package against
another source tree (a worktree of an older commit), in alternated processes: each pair's this / other.

    git worktree add /tmp/old 3d04a34 && python benchmarks/loop.py --other /tmp/old --pairs 5
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from api import alternate, ratio  # noqa: E402  (same folder)

from rovermarl.config import compose_config  # noqa: E402
from rovermarl.runner.chunk import Run, to_plain  # noqa: E402

CASES = (("solo", "1"), ("duo", "adaptive"))
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CHILD = """
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
from rovermarl.config import compose_config
from rovermarl.runner.chunk import Run, to_plain
out = {}
for setup, k in (("solo", "1"), ("duo", "adaptive")):
    run = Run(to_plain(compose_config(f"setup={setup}", f"k={k}", "generations=100000000",
                                      "algorithm.loop=compiled")), 0)
    run.advance(200)
    times = []
    for _ in range(9):
        t0 = time.process_time()
        run.advance(500)
        times.append(time.process_time() - t0)
    out[setup] = float(np.median(times))
print(json.dumps(out))
"""


def versus(other: str, pairs: int) -> dict:
    """Seconds per compiled 500-generation chunk in this package and in ``other``, alternated processes."""
    times = {"package": [], "other": []}
    for i in range(pairs):
        for name in (("other", "package") if i % 2 == 0 else ("package", "other")):
            tree = ROOT if name == "package" else os.path.abspath(other)
            done = subprocess.run([sys.executable, "-c", CHILD, tree], cwd=tree, capture_output=True, text=True,
                                  check=True, env={**os.environ, "PYTHONPATH": tree})
            times[name].append(json.loads(done.stdout.strip().splitlines()[-1]))
    out = {"benchmark": "loop_versus", "other": os.path.abspath(other)}
    for setup, _ in CASES:
        r = [p[setup] / o[setup] for p, o in zip(times["package"], times["other"], strict=True)]
        out[setup] = {"package_over_other": [round(x, 3) for x in r], "median": round(float(np.median(r)), 3)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--generations", type=int, default=500, help="generations per timed chunk")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--other", help="another source tree: its compiled way against this package's")
    ap.add_argument("--pairs", type=int, default=5, help="with --other: alternated pairs of processes")
    a = ap.parse_args()
    if a.other:
        print(json.dumps(versus(a.other, a.pairs) | {"load_average": os.getloadavg()[0]}))
        return
    out = {"benchmark": "loop", "generations": a.generations}
    for setup, k in CASES:
        runs = {loop: Run(to_plain(compose_config(f"setup={setup}", f"k={k}", "generations=100000000",
                                                  f"algorithm.loop={loop}")), 0) for loop in ("python", "compiled")}
        check = {loop: run.advance(a.generations)["score"] for loop, run in runs.items()}
        assert np.array_equal(check["python"], check["compiled"]), "the two loops differ"
        times = alternate({loop: (lambda r=run: r.advance(a.generations)) for loop, run in runs.items()},
                          dict.fromkeys(runs, 1), a.repeats, 1)
        out[f"{setup}/k={k}"] = {loop: round(float(np.median(t)), 5) for loop, t in times.items()} | {
            "python_over_compiled": ratio(times, "python", "compiled")}
    out["load_average"] = os.getloadavg()[0]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
