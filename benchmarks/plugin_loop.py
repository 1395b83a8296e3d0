"""The compiled generation loop of CC-(1+1)-ES in a world plug-in against the paper's world, for the same kernel
work: the plug-in (``twin_world.Twin``) is the paper's world with its hooks under new names, so its runs are the
paper's bit for bit (checked) and only the generated code differs. Prints one JSON line: generations per CPU second
of each and ``ratio`` = plug-in / paper (the median over repeats of the per-repeat ratio).

    python benchmarks/plugin_loop.py            # about 1 minute once compiled (setup=duo, k=adaptive)
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from api import alternate  # noqa: E402  (same folder)

from rovermarl.algorithms import compiled  # noqa: E402
from rovermarl.config import compose_config  # noqa: E402
from rovermarl.runner.chunk import Run, to_plain  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--generations", type=int, default=1000, help="generations per timed call")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--chunks", type=int, default=4)
    a = ap.parse_args()
    base = ["setup=duo", "k=adaptive", "generations=100000000", "algorithm.loop=compiled"]
    runs = {"paper": Run(to_plain(compose_config(*base)), 0),
            "plugin": Run(to_plain(compose_config(*base, "+env._target_=twin_world.Twin")), 0)}
    assert compiled.loop_of(runs["plugin"].parts.algorithm.world.compiled) is not compiled
    check = {name: run.advance(a.generations)["score"] for name, run in runs.items()}
    assert np.array_equal(check["paper"], check["plugin"]), "the twin's run is not the paper's"
    fns = {name: (lambda run=run: run.advance(a.generations)) for name, run in runs.items()}
    times = alternate(fns, dict.fromkeys(fns, a.chunks), a.repeats, a.chunks)     # one call per chunk
    rate = {name: a.generations / float(np.median(t)) for name, t in times.items()}
    print(json.dumps({"benchmark": "plugin_loop", "setup": "duo", "k": "adaptive",
                      "paper_generations_per_s": round(rate["paper"], 1),
                      "plugin_generations_per_s": round(rate["plugin"], 1),
                      "ratio": round(float(np.median(times["paper"] / times["plugin"])), 3),
                      "load_average": os.getloadavg()[0]}))


if __name__ == "__main__":
    main()
