"""Whether the kernel's hand-written LLVM intrinsics earn their place (issue 52: at least 5% in float64): this package
against copies of it with one intrinsic replaced by plain code, in alternated processes on one pinned core.

    python benchmarks/intrinsics.py --pairs 3       # each copy compiles its kernel once (a minute or more)

- ``plain_tiles``: the MLP without ``kernel/simd.py``'s register tiles (``stages._mlp``'s own plain loops, which it
  runs for what the tiles leave: ``tiles = False``);
- ``plain_pow2``: ``kernel/math.py``'s exp with ``math.ldexp(1.0, n)`` for the ``_pow2`` intrinsic.

Each process times ``World.evaluate`` of a zero-scoring duo team (prepared initial conditions) and
``World.evaluate_many`` of 64 teams on one thread (per team) in float64, process CPU time, best of ``--rounds``
rounds. Prints one JSON line: each variant's microseconds per pair, and the median over pairs of variant / package.
The copies live in ``~/.cache/rovermarl/intrinsics`` (made again when the package's source changes).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EDITS = {"plain_tiles": ("rovermarl/env/kernel/stages.py", "    tiles = genomes.strides[1] == genomes.itemsize",
                         "    tiles = False and genomes.strides[1] == genomes.itemsize"),
         "plain_pow2": ("rovermarl/env/kernel/math.py", "    return p * _pow2(n)  ",
                        "    return p * math.ldexp(1.0, n)  ")}
CHILD = """
import json, os, sys, time
import numpy as np
from rovermarl import make_world
os.sched_setaffinity(0, {int(sys.argv[1])})
rounds, n = int(sys.argv[2]), int(sys.argv[3])
world = make_world("duo")
p = world.prepare(world.run_ic(0))
teams = np.random.default_rng(0).uniform(-2, 2, (256, world.n_rovers, world.n_params))
zero = teams[np.flatnonzero(world.evaluate_many(teams, p, workers=1) == 0)[0]]
fns = {"evaluate": (lambda: world.evaluate(zero, p), n, 1),
       "many_64_per_team": (lambda: world.evaluate_many(teams[:64], p, workers=1), max(1, n // 64), 64)}
best = {}
for _ in range(rounds):
    for k, (f, m, per) in fns.items():
        t = time.process_time()
        for _ in range(m):
            f()
        best[k] = min(best.get(k, 1e9), (time.process_time() - t) / m / per * 1e6)
import rovermarl
print(json.dumps({**best, "package": rovermarl.__file__}))
"""


def copies() -> dict[str, Path | None]:
    """The package (None: as installed) and each edited copy, made once per source state."""
    src = sorted((ROOT / "rovermarl").rglob("*.py"))
    stamp = hashlib.sha256(b"".join(p.read_bytes() for p in src)).hexdigest()[:12]
    out: dict[str, Path | None] = {"package": None}
    for name, (rel, old, new) in EDITS.items():
        home = Path.home() / ".cache" / "rovermarl" / "intrinsics" / f"{name}-{stamp}"
        if not home.is_dir():
            tmp = home.with_name(home.name + ".tmp")
            shutil.rmtree(tmp, ignore_errors=True)
            for part in ("rovermarl", "conf"):
                shutil.copytree(ROOT / part, tmp / part, ignore=shutil.ignore_patterns("__pycache__"))
            text = (tmp / rel).read_text()
            if text.count(old) != 1:
                sys.exit(f"benchmarks/intrinsics.py: {rel} no longer holds {old.strip()!r} once: update EDITS")
            (tmp / rel).write_text(text.replace(old, new))
            tmp.rename(home)
        out[name] = home
    return out


def run(path: Path | None, core: int, rounds: int, n: int, child: str = CHILD, *more: str) -> dict:
    """The ``child`` program's timings (JSON) run on the package at ``path`` (None: this one) on ``core``."""
    env = dict(os.environ, PYTHONPATH=str(path)) if path else dict(os.environ)
    proc = subprocess.run([sys.executable, "-c", child, str(core), str(rounds), str(n), *more], env=env, check=True,
                          capture_output=True, text=True, cwd=path or ROOT)      # cwd: first on sys.path
    out = json.loads(proc.stdout.splitlines()[-1])
    if not out.pop("package").startswith(str(path or ROOT)):
        sys.exit(f"benchmarks/intrinsics.py: the child did not import rovermarl from {path or ROOT}")
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=3)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--calls", type=int, default=400)
    p.add_argument("--core", type=int, default=None, help="the pinned core (default: the last this process may use)")
    a = p.parse_args()
    core = sorted(os.sched_getaffinity(0))[-1] if a.core is None else a.core
    variants = copies()
    load = os.getloadavg()[0]
    for path in variants.values():
        run(path, core, 1, 2)                                     # compile (or load) each kernel first
    times = {name: [] for name in variants}
    for _ in range(a.pairs):
        for name, path in variants.items():
            times[name].append(run(path, core, a.rounds, a.calls))
    def over(name: str, k: str) -> float:
        return round(float(np.median([t[k] / b[k] for t, b in zip(times[name], times["package"], strict=True)])), 3)

    out = {"benchmark": "intrinsics", "dtype": "float64", "us": times,
           "over_package": {name: {k: over(name, k) for k in times["package"][0]} for name in EDITS},
           "loadavg_1m_start": round(load, 2), "loadavg_1m_end": round(os.getloadavg()[0], 2)}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
