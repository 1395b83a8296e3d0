"""CC-(1+1)-ES's two generation loops side by side, for the same runs: the Python loop (``algorithm.loop=python``,
:meth:`rovermarl.algorithms.cc11es.CC11ES._advance`) against the compiled one (``compiled``,
:mod:`rovermarl.algorithms.compiled`), bit-identical (checked). Prints one JSON line: CPU-seconds per chunk of each
(medians over repeats, alternated in one process) and ``python_over_compiled`` = the compiled loop's speed-up.

    python benchmarks/loop.py            # about 10 s once compiled
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from api import alternate, ratio  # noqa: E402  (same folder)

from rovermarl.config import compose_config  # noqa: E402
from rovermarl.runner.chunk import Run, to_plain  # noqa: E402

CASES = (("solo", "1"), ("duo", "adaptive"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--generations", type=int, default=500, help="generations per timed chunk")
    ap.add_argument("--repeats", type=int, default=7)
    a = ap.parse_args()
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
