"""What numba's atomic reference counts cost a single call: ``World.evaluate`` (as in ``versus.py``) in this package and
another tree (2f7d6b8, say), each with numba's reference counts atomic (as shipped) and plain (a diagnostic build),
in alternated processes on one pinned core, each arm compiled into its own empty ``NUMBA_CACHE_DIR``.

    git worktree add /tmp/old 2f7d6b8 && python benchmarks/refcounts.py /tmp/old --pairs 4

The plain build replaces ``numba.core.runtime.nrtdynmod._define_atomic_inc_dec`` (the LLVM body of ``NRT_incref`` and
``NRT_decref``'s add) with a load, an add and a store. numba's own switch for this (``_disable_atomicity``) returns the
old count, so a decref to zero never frees and every call leaks: it is not used. Diagnostic only: nothing in the
package changes. Prints one JSON line: microseconds per pair for each arm and the medians of this package / the other
tree with either build.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from versus import DTYPED, tree_args  # noqa: E402  (same folder)

ROOT = Path(__file__).resolve().parents[1]
PLAIN = '''import os
if os.environ["REFCOUNTS"] == "plain":
    import numba.core.runtime.nrtdynmod as nrt
    from llvmlite import ir

    def plain(module, op, ordering):                  # returns the new count, as the atomic one does
        fn = ir.Function(module, ir.FunctionType(nrt._word_type, [nrt._word_type.as_pointer()]), f"nrt_atomic_{op}")
        b = ir.IRBuilder(fn.append_basic_block())
        new = getattr(b, op)(b.load(fn.args[0]), ir.Constant(nrt._word_type, 1))
        b.store(new, fn.args[0])
        b.ret(new)
        return fn
    nrt._define_atomic_inc_dec = plain
'''


def main() -> None:
    a, core = tree_args(__doc__.splitlines()[0])
    trees = {"package": ROOT, "other": a.other.resolve()}
    caches = Path(tempfile.mkdtemp(prefix="rovermarl-refcounts-"))
    arms = [(tree, build) for tree in trees for build in ("atomic", "plain")]

    def run(tree: str, build: str, dtype: str, rounds: int, calls: int) -> float:
        env = dict(os.environ, PYTHONPATH=str(trees[tree]), REFCOUNTS=build,
                   NUMBA_CACHE_DIR=str(caches / f"{tree}-{build}"))
        proc = subprocess.run([sys.executable, "-c", PLAIN + DTYPED, str(core), str(rounds), str(calls), dtype],
                              env=env, cwd=trees[tree], check=True, capture_output=True, text=True)
        out = json.loads(proc.stdout.splitlines()[-1])
        if not out["package"].startswith(str(trees[tree])):
            sys.exit(f"benchmarks/refcounts.py: the child did not import rovermarl from {trees[tree]}")
        return out["evaluate"]

    load = os.getloadavg()[0]
    out = {"benchmark": "refcounts", "other": str(trees["other"])}
    for dtype in ("float32", "float64"):
        for arm in arms:
            run(*arm, dtype, 1, 2)                                      # compile each arm first
        us = {f"{t}-{b}": [] for t, b in arms}
        for _ in range(a.pairs):
            for t, b in arms:
                us[f"{t}-{b}"].append(round(run(t, b, dtype, a.rounds, a.calls), 2))
        ratio = {b: round(float(np.median(np.divide(us[f"package-{b}"], us[f"other-{b}"]))), 3)
                 for b in ("atomic", "plain")}
        out[dtype] = {"evaluate_us": us, "package_over_other": ratio}
    out |= {"loadavg_1m_start": round(load, 2), "loadavg_1m_end": round(os.getloadavg()[0], 2)}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
