"""A real training job end to end, this checkout against commit 4c4ae3c (the kernel before the speed work), in the
same run. Prints one JSON line.

    python benchmarks/end_to_end.py [--pairs 5] [--seeds 4] [--generations 20000] [--base 4c4ae3c]

The base commit is exported from git into a temporary directory (``git archive``) and run with this environment's
Python and libraries (``PYTHONPATH``), so both sides differ only in rovermarl's code. Each pair runs
``python -m rovermarl.train generations=G seeds=S parallel=serial`` once per side into fresh output dirs, in
alternating order (base first in odd pairs), so machine noise hits both alike, after one short job per side
that compiles its numba cache. Measured: the child process's CPU
time (user + system: what a shared machine inflates least) and its wall time, start-up, recording, held-out scores
and figures included. ``speedup_cpu`` is the median of the per-pair ratios base / this; ``same_final_scores``
checks that both sides logged the same median final score (the runs are bit-identical by design).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def export(commit: str, into: Path) -> Path:
    """The tree of ``commit`` as files under ``into``."""
    into.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def job(tree: Path, out: Path, generations: int, seeds: int) -> tuple[float, float, str]:
    """One training job of the rovermarl in ``tree``: (CPU seconds, wall seconds, its median-final-score line)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "rovermarl.train", f"generations={generations}", f"seeds={seeds}",
                           "parallel=serial", f"hydra.run.dir={out}"], cwd=tree, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(tree)})
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"end_to_end: the job in {tree} failed: {proc.stderr.strip().splitlines()[-1:]}")
    score = re.search(r"median final score (\S+)", proc.stdout + proc.stderr)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, score.group(1) if score else "?"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--pairs", type=int, default=5)
    p.add_argument("--seeds", type=int, default=4)
    p.add_argument("--generations", type=int, default=20000)
    p.add_argument("--base", default="4c4ae3c")
    a = p.parse_args()
    load_start = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="rovermarl-e2e-") as tmp:
        base = export(a.base, Path(tmp) / "base")
        sides = {"base": base, "this": ROOT}
        runs = {"base": [], "this": []}
        for side, tree in sides.items():                    # numba compiles (and caches) each side's kernel first
            job(tree, Path(tmp) / f"warm-{side}", 10, 1)
        for i in range(a.pairs):
            order = ("base", "this") if i % 2 == 0 else ("this", "base")
            for side in order:
                runs[side].append(job(sides[side], Path(tmp) / f"out-{side}-{i}", a.generations, a.seeds))
    cpu = {side: [r[0] for r in rs] for side, rs in runs.items()}
    wall = {side: [r[1] for r in rs] for side, rs in runs.items()}
    ratio = [b / t for b, t in zip(cpu["base"], cpu["this"], strict=True)]
    print(json.dumps({
        "benchmark": "end_to_end", "base": a.base, "pairs": a.pairs, "seeds": a.seeds,
        "generations": a.generations, "command": f"python -m rovermarl.train generations={a.generations} "
                                                  f"seeds={a.seeds} parallel=serial",
        "speedup_cpu": round(statistics.median(ratio), 3),
        "speedup_cpu_pairs": [round(x, 3) for x in ratio],
        "speedup_wall": round(statistics.median(b / t for b, t in zip(wall["base"], wall["this"], strict=True)), 3),
        "cpu_s": {side: [round(x, 2) for x in v] for side, v in cpu.items()},
        "wall_s": {side: [round(x, 2) for x in v] for side, v in wall.items()},
        "same_final_scores": len({r[2] for rs in runs.values() for r in rs}) == 1,
        "final_score": runs["this"][0][2],
        "loadavg_1m_start": round(load_start[0], 2), "loadavg_1m_end": round(os.getloadavg()[0], 2),
        "cpus": os.cpu_count(),
    }))


if __name__ == "__main__":
    main()
