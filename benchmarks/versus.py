"""This package against another source tree of rovermarl (a worktree of an older commit, say), one call at a time:
``World.evaluate`` of a zero-scoring duo team (prepared initial conditions) and ``World.evaluate_many`` of 64 teams on
one thread (per team), in float64 and float32, process CPU time, best of ``--rounds`` rounds, in alternated processes
on one pinned core (the child of ``intrinsics.py``). Prints one JSON line: each tree's microseconds per pair, and the
median over pairs of this package / the other tree.

    git worktree add /tmp/old 2f7d6b8 && python benchmarks/versus.py /tmp/old --pairs 4
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from intrinsics import CHILD, ROOT, run  # noqa: E402  (same folder)

DTYPED = CHILD.replace('world = make_world("duo")', 'world = make_world("duo", dtype=sys.argv[4])')


def tree_args(description: str) -> tuple[argparse.Namespace, int]:
    """The command line of a benchmark of this package against another tree, and the core to pin (this one's and
    ``refcounts.py``'s)."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("other", type=Path, help="the other tree's root (holding rovermarl/ and conf/)")
    p.add_argument("--pairs", type=int, default=4)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--calls", type=int, default=400)
    p.add_argument("--core", type=int, default=None, help="the pinned core (default: the last this process may use)")
    a = p.parse_args()
    if DTYPED == CHILD:
        sys.exit("benchmarks: intrinsics.CHILD no longer builds its world as make_world(\"duo\")")
    return a, sorted(os.sched_getaffinity(0))[-1] if a.core is None else a.core


def main() -> None:
    a, core = tree_args(__doc__.splitlines()[0])
    trees = {"package": None, "other": a.other.resolve()}
    load = os.getloadavg()[0]
    out = {"benchmark": "versus", "other": str(trees["other"]), "package": str(ROOT)}
    for dtype in ("float64", "float32"):
        for path in trees.values():
            run(path, core, 1, 2, DTYPED, dtype)                      # compile (or load) each kernel first
        times = {name: [] for name in trees}
        for _ in range(a.pairs):
            for name, path in trees.items():
                times[name].append(run(path, core, a.rounds, a.calls, DTYPED, dtype))
        out[dtype] = {"us": times, "package_over_other": {
            k: round(float(np.median([t[k] / o[k] for t, o in zip(times["package"], times["other"], strict=True)])), 3)
            for k in times["package"][0]}}
    out |= {"loadavg_1m_start": round(load, 2), "loadavg_1m_end": round(os.getloadavg()[0], 2)}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
